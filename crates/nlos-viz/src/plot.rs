//! Panels with axes, ticks, titles and colorbars, and multi-panel figures.

use crate::colormap::{Colormap, Norm, Scale};
use crate::error::{Result, VizError};
use crate::font::{draw_text, draw_text_vertical, text_height, text_width};
use crate::grid::{Interp, ScalarGrid, resample};
use crate::image::{Rgb, RgbImage};
use crate::ticks::{format_log_tick, format_tick, log_ticks, nice_step, nice_ticks};

/// The largest plot area side [`Panel`] accepts, in pixels.
pub const MAX_PANEL_SIDE: usize = 4096;

/// Which way the vertical axis of a panel increases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum YDirection {
    /// Upwards, as in ordinary plots and images of a wall seen from the front.
    #[default]
    Up,
    /// Downwards, as for a time axis under a space axis.
    Down,
}

/// What a panel shows.
#[derive(Debug, Clone)]
pub enum PanelContent<'a> {
    /// A scalar grid drawn as a false-colour image.
    Image {
        /// The data and their extents (which become the axis ranges).
        grid: ScalarGrid<'a>,
        /// How values map to colours.
        norm: Norm,
        /// The colours.
        colormap: Colormap,
        /// How the grid is sampled into pixels.
        interp: Interp,
        /// The colorbar's label; `None` for no colorbar.
        colorbar: Option<String>,
    },
    /// A curve `y(x)` through the points, in order.
    Line {
        /// Abscissae (their finite range becomes the x range).
        x: &'a [f64],
        /// Ordinates, as many as `x`.
        y: &'a [f64],
        /// Linear y axis from `min(0, y)` to `max(y)`, or a log axis ([`Scale::Log`], floor below max).
        y_scale: Scale,
        /// Line colour.
        color: Rgb,
    },
    /// Several curves on shared axes, with a legend in the top-right corner of the plot area.
    Lines {
        /// The curves, drawn in order (their labels listed in the legend in the same order).
        series: Vec<Series<'a>>,
        /// Linear y axis from `min(0, y)` to `max(y)`, or a log axis ([`Scale::Log`], floor below max; points
        /// with y ≤ 0 break the curve there).
        y_scale: Scale,
    },
}

/// One curve of a [`PanelContent::Lines`] panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Series<'a> {
    /// Abscissae.
    pub x: &'a [f64],
    /// Ordinates, as many as `x`.
    pub y: &'a [f64],
    /// Legend text (empty: not listed).
    pub label: String,
    /// Line colour.
    pub color: Rgb,
}

impl<'a> Series<'a> {
    /// A curve with its legend label and colour.
    pub fn new(x: &'a [f64], y: &'a [f64], label: impl Into<String>, color: Rgb) -> Self {
        Self { x, y, label: label.into(), color }
    }
}

/// Which axis a [`Marker`] sits on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkerAxis {
    /// A vertical line at an x value.
    X,
    /// A horizontal line at a y value.
    Y,
}

/// A dashed reference line with a short label, e.g. a gate position.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// The axis the value belongs to.
    pub axis: MarkerAxis,
    /// The position in axis units; markers outside the range are not drawn.
    pub value: f64,
    /// Text drawn beside the line.
    pub label: String,
    /// Line and text colour.
    pub color: Rgb,
}

/// One plot: a content area of `width × height` pixels with a frame, ticks, tick labels, axis titles, a
/// title above, and for images an optional colorbar.
///
/// # Example
/// ```
/// use nlos_viz::{Extent, Norm, Panel, Scale, ScalarGrid};
/// let v: Vec<f32> = (0..16).map(|i| i as f32).collect();
/// let g = ScalarGrid::new(&v, 4, 4, Extent::new(-0.2, 0.2)?, Extent::new(-0.2, 0.2)?)?;
/// let panel = Panel::image(g, Norm::auto(&v, Scale::Linear)?)
///     .with_title("ramp")
///     .with_labels("x (m)", "y (m)")
///     .with_colorbar("counts");
/// let img = panel.render(1)?;
/// assert!(img.width() > panel.width && img.height() > panel.height);
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// Title drawn above the plot area.
    pub title: String,
    /// Title of the x axis.
    pub x_label: String,
    /// Title of the y axis.
    pub y_label: String,
    /// Which way y increases.
    pub y_direction: YDirection,
    /// The data.
    pub content: PanelContent<'a>,
    /// Reference lines.
    pub markers: Vec<Marker>,
    /// Width of the plot area in pixels.
    pub width: usize,
    /// Height of the plot area in pixels.
    pub height: usize,
}

impl<'a> Panel<'a> {
    /// An image panel of 320 × 320 pixels, viridis, nearest sampling, no colorbar, y up.
    pub fn image(grid: ScalarGrid<'a>, norm: Norm) -> Self {
        Self::new(PanelContent::Image {
            grid,
            norm,
            colormap: Colormap::Viridis,
            interp: Interp::Nearest,
            colorbar: None,
        })
    }

    /// A line panel of 480 × 320 pixels with a linear y axis.
    ///
    /// # Errors
    /// [`VizError::InvalidArgument`] when the lengths differ or no point is finite.
    pub fn line(x: &'a [f64], y: &'a [f64]) -> Result<Self> {
        if x.len() != y.len() || !x.iter().zip(y).any(|(a, b)| a.is_finite() && b.is_finite()) {
            return Err(VizError::InvalidArgument {
                name: "x, y",
                reason: format!("{} x and {} y values: need equal lengths and a finite point", x.len(), y.len()),
            });
        }
        let mut p = Self::new(PanelContent::Line { x, y, y_scale: Scale::Linear, color: Rgb::BLUE });
        p.width = 480;
        Ok(p)
    }

    /// A panel of several curves on shared axes with a legend, 480 × 320 pixels, linear y axis.
    ///
    /// # Example
    /// ```
    /// use nlos_viz::{Panel, Rgb, Scale, Series};
    /// let x: Vec<f64> = (0..50).map(f64::from).collect();
    /// let a: Vec<f64> = x.iter().map(|i| 1.0 / (1.0 + i)).collect();
    /// let b: Vec<f64> = x.iter().map(|i| 0.1 / (1.0 + i * i)).collect();
    /// let p = Panel::lines(vec![Series::new(&x, &a, "total", Rgb::BLACK), Series::new(&x, &b, "reg.", Rgb::RED)])?
    ///     .with_y_scale(Scale::Log { decades: 4.0 })
    ///     .with_labels("iteration", "loss");
    /// assert!(p.render(1)?.width() > 480);
    /// # Ok::<(), nlos_viz::VizError>(())
    /// ```
    ///
    /// # Errors
    /// [`VizError::InvalidArgument`] with no series, a series whose lengths differ, or no finite point in
    /// any series.
    pub fn lines(series: Vec<Series<'a>>) -> Result<Self> {
        if series.is_empty() {
            return Err(VizError::InvalidArgument { name: "series", reason: "need at least one curve".into() });
        }
        if let Some(s) = series.iter().find(|s| s.x.len() != s.y.len()) {
            return Err(VizError::InvalidArgument {
                name: "series",
                reason: format!("curve `{}` has {} x and {} y values", s.label, s.x.len(), s.y.len()),
            });
        }
        if !series.iter().any(|s| s.x.iter().zip(s.y).any(|(a, b)| a.is_finite() && b.is_finite())) {
            return Err(VizError::InvalidArgument { name: "series", reason: "no finite point in any curve".into() });
        }
        let mut p = Self::new(PanelContent::Lines { series, y_scale: Scale::Linear });
        p.width = 480;
        Ok(p)
    }

    fn new(content: PanelContent<'a>) -> Self {
        Self {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            y_direction: YDirection::Up,
            content,
            markers: Vec::new(),
            width: 320,
            height: 320,
        }
    }

    /// Sets the title.
    pub fn with_title(mut self, title: impl Into<String>) -> Self {
        self.title = title.into();
        self
    }

    /// Sets the axis titles.
    pub fn with_labels(mut self, x: impl Into<String>, y: impl Into<String>) -> Self {
        self.x_label = x.into();
        self.y_label = y.into();
        self
    }

    /// Sets the plot area size in pixels.
    pub fn with_size(mut self, width: usize, height: usize) -> Self {
        self.width = width;
        self.height = height;
        self
    }

    /// Sets the direction of the y axis.
    pub fn with_y_direction(mut self, d: YDirection) -> Self {
        self.y_direction = d;
        self
    }

    /// Sets the colormap of an image panel (no effect on a line panel).
    pub fn with_colormap(mut self, cm: Colormap) -> Self {
        if let PanelContent::Image { colormap, .. } = &mut self.content {
            *colormap = cm;
        }
        self
    }

    /// Sets the sampling of an image panel (no effect on a line panel).
    pub fn with_interp(mut self, i: Interp) -> Self {
        if let PanelContent::Image { interp, .. } = &mut self.content {
            *interp = i;
        }
        self
    }

    /// Adds a colorbar with this label to an image panel (no effect on a line panel).
    pub fn with_colorbar(mut self, label: impl Into<String>) -> Self {
        if let PanelContent::Image { colorbar, .. } = &mut self.content {
            *colorbar = Some(label.into());
        }
        self
    }

    /// Sets the y scale of a line panel (no effect on an image panel).
    pub fn with_y_scale(mut self, s: Scale) -> Self {
        if let PanelContent::Line { y_scale, .. } | PanelContent::Lines { y_scale, .. } = &mut self.content {
            *y_scale = s;
        }
        self
    }

    /// Adds a reference line.
    pub fn with_marker(mut self, axis: MarkerAxis, value: f64, label: impl Into<String>, color: Rgb) -> Self {
        self.markers.push(Marker { axis, value, label: label.into(), color });
        self
    }

    /// The axis maps (x, y) from data units to `[0, 1]`.
    fn axes(&self) -> Result<(Norm, Norm)> {
        match &self.content {
            PanelContent::Image { grid, .. } => {
                let (x, y) = (grid.x_extent(), grid.y_extent());
                Ok((Norm::linear(x.min(), x.max())?, Norm::linear(y.min(), y.max())?))
            }
            PanelContent::Line { x, y, y_scale, .. } => line_axes(&[(x, y)], *y_scale),
            PanelContent::Lines { series, y_scale } => {
                let curves: Vec<(&[f64], &[f64])> = series.iter().map(|s| (s.x, s.y)).collect();
                line_axes(&curves, *y_scale)
            }
        }
    }

    /// Renders the panel (plot area plus its margins) at text scale `scale` (1 = 5 × 7 pixel glyphs).
    ///
    /// # Errors
    /// [`VizError::InvalidSize`] when the plot area is empty or larger than [`MAX_PANEL_SIDE`], or the text
    /// scale is not in 1..=8; errors of the content.
    pub fn render(&self, scale: usize) -> Result<RgbImage> {
        self.render_on(scale, Rgb::WHITE)
    }

    fn render_on(&self, s: usize, bg: Rgb) -> Result<RgbImage> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 || w > MAX_PANEL_SIDE || h > MAX_PANEL_SIDE {
            return Err(VizError::InvalidSize {
                width: w,
                height: h,
                reason: format!("a plot area side must be in 1..={MAX_PANEL_SIDE} pixels"),
            });
        }
        if !(1..=8).contains(&s) {
            return Err(VizError::InvalidArgument { name: "scale", reason: format!("text scale {s} not in 1..=8") });
        }
        let (xn, yn) = self.axes()?;
        let ch = text_height(s);
        let (pad, gap, tick) = (4 * s, 2 * s, 4 * s);

        let along_x = |l: &str| text_width(l, s);
        let along_y = |_: &str| ch;
        let x_ticks = axis_ticks(&xn, w, 2 * ch, &along_x);
        let y_ticks = axis_ticks(&yn, h, 2 * ch, &along_y);
        let y_label_w = y_ticks.iter().map(|(_, l)| text_width(l, s)).max().unwrap_or(0);

        let colorbar = match &self.content {
            PanelContent::Image { norm, colormap, colorbar: Some(label), .. } => {
                let ticks = axis_ticks(norm, h, 2 * ch, &along_y);
                let lw = ticks.iter().map(|(_, l)| text_width(l, s)).max().unwrap_or(0);
                Some((norm, *colormap, label.as_str(), ticks, lw))
            }
            _ => None,
        };
        let bar_w = 4 * ch / 2;
        let right = match &colorbar {
            Some((_, _, label, _, lw)) => {
                3 * gap * 2 + bar_w + tick + gap + lw + if label.is_empty() { 0 } else { 2 * gap + ch } + pad
            }
            None => text_width("-0.00", s) / 2 + pad,
        };
        let left = pad + if self.y_label.is_empty() { 0 } else { ch + 2 * gap } + y_label_w + gap + tick + 1;
        let top = pad + if self.title.is_empty() { 0 } else { ch + 2 * gap };
        let bottom = 1 + tick + gap + ch + if self.x_label.is_empty() { 0 } else { 2 * gap + ch } + pad;
        let total_w = (left + w + right).max(text_width(&self.title, s) + 2 * pad);
        let mut img = RgbImage::new(total_w, top + h + bottom, bg)?;
        let (px0, py0) = (left as i64, top as i64);
        let (wi, hi) = (w as i64, h as i64);

        // Content.
        match &self.content {
            PanelContent::Image { grid, norm, colormap, interp, .. } => {
                let y_down = self.y_direction == YDirection::Down;
                let vals = resample(grid, w, h, *interp, y_down)?;
                for (i, v) in vals.iter().enumerate() {
                    let c = if v.is_finite() { colormap.map(norm.apply(f64::from(*v))) } else { Rgb::GREY };
                    img.set(px0 + (i % w) as i64, py0 + (i / w) as i64, c);
                }
            }
            PanelContent::Line { x, y, color, .. } => {
                let area = Area { origin: (px0, py0), size: (w, h), axes: (&xn, &yn), dir: self.y_direction };
                polyline(&mut img, &area, (x, y), *color, false);
            }
            PanelContent::Lines { series, y_scale } => {
                let log = matches!(y_scale, Scale::Log { .. });
                let area = Area { origin: (px0, py0), size: (w, h), axes: (&xn, &yn), dir: self.y_direction };
                for sr in series {
                    polyline(&mut img, &area, (sr.x, sr.y), sr.color, log);
                }
                // Legend: a boxed list of colour swatches and labels in the top-right corner.
                let listed: Vec<&Series<'_>> = series.iter().filter(|sr| !sr.label.is_empty()).collect();
                if !listed.is_empty() {
                    let sw = 6 * s as i64;
                    let lw = listed.iter().map(|sr| text_width(&sr.label, s)).max().unwrap_or(0) as i64;
                    let row = (ch + gap) as i64;
                    let bw = gap as i64 * 3 + sw + lw + gap as i64;
                    let bh = row * listed.len() as i64 + gap as i64;
                    let (bx, by) = (px0 + wi - bw - gap as i64, py0 + gap as i64);
                    img.fill_rect(bx, by, bw, bh, bg);
                    img.rect_outline(bx, by, bw, bh, Rgb::GREY);
                    for (k, sr) in listed.iter().enumerate() {
                        let y = by + gap as i64 + row * k as i64;
                        img.fill_rect(bx + gap as i64, y + (ch as i64) / 2 - s as i64, sw, 2 * s as i64, sr.color);
                        draw_text(&mut img, bx + 2 * gap as i64 + sw, y, &sr.label, Rgb::BLACK, s);
                    }
                }
            }
        }

        // Markers, dashed, with their labels inside the plot area.
        for m in &self.markers {
            let (norm, along) = match m.axis {
                MarkerAxis::X => (&xn, w),
                MarkerAxis::Y => (&yn, h),
            };
            let (lo, hi_v) = norm.range();
            if !(m.value.is_finite() && m.value >= lo && m.value <= hi_v) {
                continue;
            }
            let flip = m.axis == MarkerAxis::Y && self.y_direction == YDirection::Up;
            let p = pos(norm, m.value, along, flip);
            let dash = 4 * s as i64;
            match m.axis {
                MarkerAxis::X => {
                    for k in (0..hi).step_by(2 * dash as usize) {
                        img.fill_rect(px0 + p, py0 + k, s as i64, dash.min(hi - k), m.color);
                    }
                    draw_text(&mut img, px0 + p + gap as i64, py0 + gap as i64, &m.label, m.color, s);
                }
                MarkerAxis::Y => {
                    for k in (0..wi).step_by(2 * dash as usize) {
                        img.fill_rect(px0 + k, py0 + p, dash.min(wi - k), s as i64, m.color);
                    }
                    let ty = if p > (ch + gap) as i64 { py0 + p - (ch + gap) as i64 } else { py0 + p + gap as i64 };
                    draw_text(&mut img, px0 + gap as i64, ty, &m.label, m.color, s);
                }
            }
        }

        // Frame, ticks and labels.
        img.rect_outline(px0 - 1, py0 - 1, wi + 2, hi + 2, Rgb::BLACK);
        let tk = tick as i64;
        for (v, label) in &x_ticks {
            let x = px0 + pos(&xn, *v, w, false);
            img.fill_rect(x, py0 + hi + 1, s as i64, tk, Rgb::BLACK);
            let tw = text_width(label, s) as i64;
            draw_text(&mut img, x - tw / 2, py0 + hi + 1 + tk + gap as i64, label, Rgb::BLACK, s);
        }
        let up = self.y_direction == YDirection::Up;
        for (v, label) in &y_ticks {
            let y = py0 + pos(&yn, *v, h, up);
            img.fill_rect(px0 - 1 - tk, y, tk, s as i64, Rgb::BLACK);
            let tw = text_width(label, s) as i64;
            draw_text(&mut img, px0 - 1 - tk - gap as i64 - tw, y - (7 * s / 2) as i64, label, Rgb::BLACK, s);
        }
        if !self.x_label.is_empty() {
            let tw = text_width(&self.x_label, s) as i64;
            let y = py0 + hi + 1 + tk + (3 * gap + ch) as i64;
            draw_text(&mut img, (px0 + wi / 2 - tw / 2).max(0), y, &self.x_label, Rgb::BLACK, s);
        }
        if !self.y_label.is_empty() {
            let tl = text_width(&self.y_label, s) as i64;
            draw_text_vertical(&mut img, pad as i64, (py0 + hi / 2 - tl / 2).max(0), &self.y_label, Rgb::BLACK, s);
        }
        if !self.title.is_empty() {
            let tw = text_width(&self.title, s) as i64;
            let x = (px0 + wi / 2 - tw / 2).clamp(pad as i64, (total_w - pad) as i64 - tw);
            draw_text(&mut img, x.max(0), pad as i64, &self.title, Rgb::BLACK, s);
        }

        // Colorbar.
        if let Some((norm, cm, label, ticks, lw)) = colorbar {
            let bx = px0 + wi + 1 + (3 * gap * 2) as i64;
            for r in 0..h {
                let t = 1.0 - (r as f32 + 0.5) / h as f32;
                img.fill_rect(bx, py0 + r as i64, bar_w as i64, 1, cm.map(t));
            }
            img.rect_outline(bx - 1, py0 - 1, bar_w as i64 + 2, hi + 2, Rgb::BLACK);
            let tx = bx + bar_w as i64 + 1;
            for (v, l) in &ticks {
                let y = py0 + pos(norm, *v, h, true);
                img.fill_rect(tx, y, tk, s as i64, Rgb::BLACK);
                draw_text(&mut img, tx + tk + gap as i64, y - (7 * s / 2) as i64, l, Rgb::BLACK, s);
            }
            if !label.is_empty() {
                let tl = text_width(label, s) as i64;
                let x = tx + tk + (gap + lw + 2 * gap) as i64;
                draw_text_vertical(&mut img, x, (py0 + hi / 2 - tl / 2).max(0), label, Rgb::BLACK, s);
            }
        }
        Ok(img)
    }
}

/// The (x, y) axis maps of line plots over all finite points of `curves`.
fn line_axes(curves: &[(&[f64], &[f64])], y_scale: Scale) -> Result<(Norm, Norm)> {
    let pts =
        || curves.iter().flat_map(|(x, y)| x.iter().zip(y.iter())).filter(|(a, b)| a.is_finite() && b.is_finite());
    let (x0, x1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |r, (a, _)| (r.0.min(*a), r.1.max(*a)));
    let (y0, y1) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |r, (_, b)| (r.0.min(*b), r.1.max(*b)));
    if !x0.is_finite() {
        return Err(VizError::InvalidArgument { name: "x, y", reason: "no finite point".into() });
    }
    let xn = if x1 > x0 { Norm::linear(x0, x1)? } else { Norm::linear(x0 - 0.5, x0 + 0.5)? };
    let yn = match y_scale {
        Scale::Linear => {
            let lo = y0.min(0.0);
            let hi = if y1 > lo { y1 + 0.05 * (y1 - lo) } else { lo + 1.0 };
            Norm::linear(lo, hi)?
        }
        Scale::Log { decades } => Norm::log(if y1 > 0.0 { y1 * 1.2 } else { 1.0 }, decades)?,
    };
    Ok((xn, yn))
}

/// A panel's plot area: its top-left pixel, its size in pixels, the axes' maps from data to `[0, 1]` and the
/// direction of y.
struct Area<'a> {
    origin: (i64, i64),
    size: (usize, usize),
    axes: (&'a Norm, &'a Norm),
    dir: YDirection,
}

/// Draws the curve `(x, y)` in the plot area `area`; non-finite points (and, with `skip_nonpositive`, points
/// with y ≤ 0) break it.
fn polyline(img: &mut RgbImage, area: &Area<'_>, (x, y): (&[f64], &[f64]), color: Rgb, skip_nonpositive: bool) {
    let Area { origin, size, axes, dir } = *area;
    let mut prev: Option<(i64, i64)> = None;
    for (&a, &b) in x.iter().zip(y.iter()) {
        if !(a.is_finite() && b.is_finite()) || (skip_nonpositive && b <= 0.0) {
            prev = None;
            continue;
        }
        let p = (origin.0 + pos(axes.0, a, size.0, false), origin.1 + pos(axes.1, b, size.1, dir == YDirection::Up));
        match prev {
            Some(q) => img.line(q.0, q.1, p.0, p.1, color),
            None => img.set(p.0, p.1, color),
        }
        prev = Some(p);
    }
}

/// Pixel offset of `v` along an axis of `n` pixels (0 at the low end, or at the high end when `flip`).
fn pos(norm: &Norm, v: f64, n: usize, flip: bool) -> i64 {
    let t = f64::from(norm.apply(v));
    let p = ((t * n as f64).floor() as i64).clamp(0, n as i64 - 1);
    if flip { n as i64 - 1 - p } else { p }
}

/// Tick values and labels for an axis of `len` pixels: the most ticks whose labels keep `gap` pixels
/// between neighbours, where `extent` gives a label's size along the axis (its width on a horizontal axis).
fn axis_ticks(norm: &Norm, len: usize, gap: usize, extent: &dyn Fn(&str) -> usize) -> Vec<(f64, String)> {
    let (lo, hi) = norm.range();
    let fits = |ticks: &[(f64, String)]| {
        ticks.windows(2).all(|p| {
            let d = (f64::from(norm.apply(p[1].0)) - f64::from(norm.apply(p[0].0))).abs() * len as f64;
            d >= ((extent(&p[0].1) + extent(&p[1].1)) / 2 + gap) as f64
        })
    };
    let candidates: Vec<Vec<(f64, String)>> = match norm.scale() {
        Scale::Log { .. } => {
            let t = log_ticks(lo, hi);
            (1..=t.len().max(1))
                .map(|stride| t.iter().step_by(stride).map(|&v| (v, format_log_tick(v))).collect())
                .collect()
        }
        Scale::Linear => (2..=(len / gap.max(1)).clamp(2, 40))
            .rev()
            .map(|n| {
                let step = nice_step(hi - lo, n).unwrap_or(1.0);
                nice_ticks(lo, hi, n).into_iter().map(|v| (v, format_tick(v, step))).collect()
            })
            .collect(),
    };
    candidates.iter().find(|t| fits(t)).or(candidates.last()).cloned().unwrap_or_default()
}

/// Panels laid out in rows under a title and optional note lines.
///
/// # Example
/// ```
/// use nlos_viz::{Extent, Figure, Norm, Panel, Scale, ScalarGrid};
/// let v = vec![1.0f32; 64];
/// let g = ScalarGrid::new(&v, 8, 8, Extent::new(0.0, 1.0)?, Extent::new(0.0, 1.0)?)?;
/// let mut fig = Figure::new("two panels");
/// fig.notes.push("a note".into());
/// fig.panels.push(Panel::image(g, Norm::auto(&v, Scale::Linear)?).with_size(100, 100));
/// fig.panels.push(Panel::image(g, Norm::auto(&v, Scale::Linear)?).with_size(100, 100));
/// let img = fig.render()?;
/// assert!(img.width() > 200);
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Figure<'a> {
    /// Title across the top (drawn one text size larger when it fits).
    pub title: String,
    /// Lines of small text under the title.
    pub notes: Vec<String>,
    /// The panels, row by row.
    pub panels: Vec<Panel<'a>>,
    /// Panels per row; 0 puts them all in one row.
    pub columns: usize,
    /// Text scale (1..=8): 2 draws glyphs of 10 × 14 pixels.
    pub text_scale: usize,
    /// Background colour.
    pub background: Rgb,
}

impl<'a> Figure<'a> {
    /// An empty figure with a title, one row, text scale 2, white background.
    pub fn new(title: impl Into<String>) -> Self {
        Self {
            title: title.into(),
            notes: Vec::new(),
            panels: Vec::new(),
            columns: 0,
            text_scale: 2,
            background: Rgb::WHITE,
        }
    }

    /// Renders every panel and lays them out.
    ///
    /// # Errors
    /// [`VizError::InvalidArgument`] with no panel or a text scale outside 1..=8; the panels' errors;
    /// [`VizError::InvalidSize`] when the figure would exceed [`MAX_DIMENSION`](crate::MAX_DIMENSION).
    pub fn render(&self) -> Result<RgbImage> {
        let s = self.text_scale;
        if !(1..=8).contains(&s) {
            return Err(VizError::InvalidArgument { name: "text_scale", reason: format!("{s} not in 1..=8") });
        }
        if self.panels.is_empty() {
            return Err(VizError::InvalidArgument { name: "panels", reason: "a figure needs a panel".into() });
        }
        let rendered = self.panels.iter().map(|p| p.render_on(s, self.background)).collect::<Result<Vec<_>>>()?;
        let cols = if self.columns == 0 { rendered.len() } else { self.columns };
        let pad = 6 * s;
        let rows: Vec<&[RgbImage]> = rendered.chunks(cols).collect();
        let row_w = |r: &[RgbImage]| r.iter().map(RgbImage::width).sum::<usize>() + pad * r.len().saturating_sub(1);
        let panels_w = rows.iter().map(|r| row_w(r)).max().unwrap_or(0);
        let ts = if text_width(&self.title, s + 1) <= panels_w { s + 1 } else { s };
        let mut header = if self.title.is_empty() { 0 } else { text_height(ts) + 2 * s };
        header += self.notes.len() * (text_height(s) + 2 * s);
        let text_w = self
            .notes
            .iter()
            .map(|n| text_width(n, s))
            .chain(std::iter::once(text_width(&self.title, ts)))
            .max()
            .unwrap_or(0);
        let width = panels_w.max(text_w) + 2 * pad;
        let height = pad
            + header
            + rows.iter().map(|r| r.iter().map(RgbImage::height).max().unwrap_or(0)).sum::<usize>()
            + pad * rows.len();
        let mut img = RgbImage::new(width, height, self.background)?;
        let mut y = pad as i64;
        if !self.title.is_empty() {
            let tw = text_width(&self.title, ts);
            draw_text(&mut img, ((width - tw) / 2) as i64, y, &self.title, Rgb::BLACK, ts);
            y += (text_height(ts) + 2 * s) as i64;
        }
        for n in &self.notes {
            let tw = text_width(n, s);
            draw_text(&mut img, ((width - tw) / 2) as i64, y, n, Rgb::new(64, 64, 64), s);
            y += (text_height(s) + 2 * s) as i64;
        }
        for r in rows {
            let mut x = (pad + (panels_w.max(text_w) - row_w(r)) / 2) as i64;
            for p in r {
                img.blit(p, x, y);
                x += (p.width() + pad) as i64;
            }
            y += (r.iter().map(RgbImage::height).max().unwrap_or(0) + pad) as i64;
        }
        Ok(img)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Extent;

    #[test]
    fn image_panel_places_data_and_frame() {
        // Left half 0, right half 1, in a 2 × 1 grid; viridis ends.
        let v = [0.0, 1.0];
        let g = ScalarGrid::new(&v, 2, 1, Extent::new(0.0, 1.0).expect("e"), Extent::new(0.0, 1.0).expect("e"))
            .expect("grid");
        let p = Panel::image(g, Norm::linear(0.0, 1.0).expect("norm")).with_size(10, 4).with_labels("x", "y");
        let img = p.render(1).expect("render");
        // Find the frame: the plot area is where viridis' low colour starts.
        let low = Colormap::Viridis.map(0.0);
        let high = Colormap::Viridis.map(1.0);
        let (x0, y0) = (0..img.height())
            .flat_map(|y| (0..img.width()).map(move |x| (x, y)))
            .find(|&(x, y)| img.get(x, y) == Some(low))
            .expect("plot area");
        assert_eq!(img.get(x0 + 4, y0 + 3), Some(low));
        assert_eq!(img.get(x0 + 5, y0), Some(high));
        assert_eq!(img.get(x0 + 9, y0 + 3), Some(high));
        assert_eq!(img.get(x0 - 1, y0), Some(Rgb::BLACK));
        assert_eq!(img.get(x0 + 10, y0 + 4), Some(Rgb::BLACK));
    }

    #[test]
    fn line_panel_and_markers_render() {
        let x: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        let y: Vec<f64> = x.iter().map(|v| (v * 6.0).sin().abs() * 1000.0).collect();
        let p = Panel::line(&x, &y)
            .expect("line")
            .with_y_scale(Scale::Log { decades: 3.0 })
            .with_marker(MarkerAxis::X, 0.5, "gate", Rgb::RED)
            .with_marker(MarkerAxis::X, 50.0, "off axis", Rgb::RED);
        let img = p.render(2).expect("render");
        let blue = (0..img.height()).flat_map(|y| (0..img.width()).map(move |x| (x, y)));
        assert!(blue.clone().any(|(x, y)| img.get(x, y) == Some(Rgb::BLUE)));
        assert!(blue.clone().any(|(x, y)| img.get(x, y) == Some(Rgb::RED)));
        assert!(Panel::line(&x, &y[..3]).is_err());
        assert!(Panel::line(&[f64::NAN], &[1.0]).is_err());
    }

    #[test]
    fn lines_panel_draws_every_series_and_a_legend() {
        let x: Vec<f64> = (0..100).map(f64::from).collect();
        let a: Vec<f64> = x.iter().map(|i| 100.0 / (1.0 + i)).collect();
        let b: Vec<f64> = x.iter().map(|i| if *i < 50.0 { 1.0 } else { 0.0 }).collect();
        let green = Rgb::new(0, 160, 0);
        let p = Panel::lines(vec![Series::new(&x, &a, "total", Rgb::BLUE), Series::new(&x, &b, "step", green)])
            .expect("lines")
            .with_y_scale(Scale::Log { decades: 3.0 })
            .with_marker(MarkerAxis::X, 50.0, "stage 2", Rgb::RED);
        let img = p.render(1).expect("render");
        let count = |c: Rgb| {
            (0..img.height())
                .flat_map(|y| (0..img.width()).map(move |x| (x, y)))
                .filter(|&(x, y)| img.get(x, y) == Some(c))
                .count()
        };
        // Both curves and the legend swatches are drawn; the zeros of `b` (log axis) are a gap, so its
        // pixels are only the 50 points of 1.0 (a horizontal run) plus the swatch.
        let (blue, gr) = (count(Rgb::BLUE), count(green));
        assert!(blue > 100, "{blue} blue pixels");
        assert!(gr > 20 && gr < 480, "{gr} green pixels");
        assert!(count(Rgb::RED) > 0);
        assert!(Panel::lines(vec![]).is_err());
        assert!(Panel::lines(vec![Series::new(&x, &a[..3], "bad", Rgb::BLUE)]).is_err());
        assert!(Panel::lines(vec![Series::new(&[f64::NAN], &[1.0], "nan", Rgb::BLUE)]).is_err());
    }

    #[test]
    fn bad_sizes_are_errors() {
        let v = [1.0f32];
        let e = Extent::new(0.0, 1.0).expect("e");
        let g = ScalarGrid::new(&v, 1, 1, e, e).expect("grid");
        let n = Norm::linear(0.0, 1.0).expect("norm");
        assert!(Panel::image(g, n).with_size(0, 5).render(1).is_err());
        assert!(Panel::image(g, n).with_size(5, 100_000).render(1).is_err());
        assert!(Panel::image(g, n).render(0).is_err());
        assert!(Figure::new("empty").render().is_err());
    }

    #[test]
    fn figure_lays_out_rows() {
        let v = [1.0f32; 4];
        let e = Extent::new(0.0, 1.0).expect("e");
        let g = ScalarGrid::new(&v, 2, 2, e, e).expect("grid");
        let n = Norm::linear(0.0, 2.0).expect("norm");
        let mut f = Figure::new("t");
        f.panels = vec![Panel::image(g, n).with_size(50, 50); 4];
        f.columns = 2;
        let two_rows = f.render().expect("render");
        f.columns = 0;
        let one_row = f.render().expect("render");
        assert!(two_rows.height() > one_row.height() && two_rows.width() < one_row.width());
    }
}
