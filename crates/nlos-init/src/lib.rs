//! # nlos-init
//!
//! Volumetric non-line-of-sight reconstructions and the step that turns them into the initial surface
//! of the optimiser (Tsai, Sankaranarayanan & Gkioulekas, CVPR 2019, Sec. 6–7):
//!
//! - [`lct()`]: the light-cone transform with Wiener deconvolution (O'Toole, Lindell & Wetzstein,
//!   Nature 2018), confocal grid scans;
//! - [`fk()`]: f-k (Stolt) migration (Lindell, Wetzstein & O'Toole, SIGGRAPH 2019), confocal grid scans;
//! - [`fbp()`]: Laplacian-filtered backprojection (the LCT's adjoint) for confocal grid scans, direct
//!   ellipsoidal backprojection for exhaustive scans with a sensor grid;
//! - [`pf()`]: phasor-field reconstruction (Liu et al., Nature 2019) for any scan: confocal, one laser and
//!   a sensor grid, many lasers × many sensors, wall points on a grid or in a list;
//! - [`carve()`]: space carving from first-returning photons (Tsai et al., CVPR 2017), confocal or
//!   exhaustive scans with a sensor grid;
//! - [`volume_to_surface`]: per-column maximum, threshold (Otsu or explicit), largest connected region,
//!   grid triangulation facing the wall, optional smoothing and isotropic remeshing.
//!
//! Conventions are the workspace's: metres, wall z = 0 with normal +z, times are path lengths
//! `l → x → s` (so a confocal voxel at depth z answers at path `2z`), data measurement-major with grid
//! points `ix + nx·iy`. A [`Volume`] keeps the scan's x and y grid and adds depth.
//!
//! ```
//! use nlos_init::{Gate, LctParams, SurfaceParams, lct, volume_to_surface};
//! use nlos_transient::{PointSet, Scan, TimeAxis, Transient};
//! // A flat patch 0.3 m away, 8 × 8 scan, 1 cm bins: every point sees the patch straight ahead.
//! let scan = Scan::confocal(PointSet::wall_grid(8, 8, 0.1, 0.1)?);
//! let mut t = Transient::zeros(scan, TimeAxis::new(0.0, 0.01, 128)?)?;
//! for m in 0..64 {
//!     t.histogram_mut(m)[60] = 1.0;
//! }
//! let vol = lct(&t, &LctParams { gate: Gate::None, ..LctParams::default() })?;
//! let surface = volume_to_surface(&vol, &SurfaceParams::default())?;
//! assert!((surface.median_depth().unwrap() - 0.3025).abs() < 0.011);
//! # Ok::<(), nlos_init::InitError>(())
//! ```
#![warn(missing_docs)]

pub mod carve;
pub mod error;
pub mod fbp;
mod fft;
pub mod fk;
pub mod front_view;
pub mod lct;
pub mod method;
pub mod pf;
mod prep;
pub mod rim;
pub mod surface;
pub mod volume;

pub use carve::{CarveParams, carve, first_returns};
pub use error::{InitError, Result};
pub use fbp::{FbpParams, fbp};
pub use fk::{FkParams, fk};
pub use front_view::{FrontViewDetail, front_view_detail};
pub use lct::{LctParams, lct};
pub use method::{InitMethod, Method, lct_params};
pub use nlos_brdf::Model;
pub use pf::{DepthNoise, PfParams, pf};
pub use prep::Gate;
pub use rim::round_rim;
pub use surface::{
    GrowReference, Surface, SurfaceParams, Threshold, connected_components, otsu_threshold, volume_to_surface,
    volume_to_surface_where,
};
pub use volume::{Axis, Volume};
