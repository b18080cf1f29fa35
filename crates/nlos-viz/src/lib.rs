//! # nlos-viz
//!
//! Raster figures without a plotting stack: an RGB image buffer, colormaps (viridis, magma, grey), linear
//! and logarithmic value scaling, nearest/bilinear/area resampling of scalar grids with physical extents,
//! an embedded 5 × 7 bitmap font, axes with "nice" ticks, colorbars, multi-panel layout and PNG output.
//!
//! The crate knows nothing about transients or file formats: it draws `&[f32]` grids (x fastest) and
//! `(x, y)` curves in whatever units their extents are given in.
//!
//! ## Example
//! ```
//! use nlos_viz::{Colormap, Extent, Figure, Norm, Panel, Scale, ScalarGrid, YDirection};
//! // A 32 × 32 Gaussian blob on a wall 0.5 m wide.
//! let n = 32;
//! let v: Vec<f32> = (0..n * n)
//!     .map(|i| {
//!         let (x, y) = ((i % n) as f32 - 16.0, (i / n) as f32 - 16.0);
//!         (-(x * x + y * y) / 40.0).exp()
//!     })
//!     .collect();
//! let wall = Extent::from_centres(-0.25, 0.25, n)?;
//! let grid = ScalarGrid::new(&v, n, n, wall, wall)?;
//! let mut fig = Figure::new("blob");
//! fig.panels.push(
//!     Panel::image(grid, Norm::auto(&v, Scale::Log { decades: 3.0 })?)
//!         .with_colormap(Colormap::Magma)
//!         .with_labels("x (m)", "y (m)")
//!         .with_colorbar("intensity"),
//! );
//! let png = fig.render()?.encode_png()?;
//! assert!(png.starts_with(b"\x89PNG"));
//! # Ok::<(), nlos_viz::VizError>(())
//! ```
#![warn(missing_docs)]

pub mod colormap;
pub mod error;
pub mod font;
pub mod grid;
pub mod image;
pub mod plot;
mod tables;
pub mod ticks;

pub use colormap::{Colormap, Norm, Scale};
pub use error::{Result, VizError};
pub use font::{draw_text, draw_text_vertical, text_height, text_width};
pub use grid::{Extent, Interp, ScalarGrid, resample};
pub use image::{MAX_DIMENSION, Rgb, RgbImage};
pub use plot::{Figure, MAX_PANEL_SIDE, Marker, MarkerAxis, Panel, PanelContent, Series, YDirection};
pub use ticks::{format_log_tick, format_tick, log_ticks, nice_step, nice_ticks};
