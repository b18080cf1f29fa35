//! `nlos.Renderer` (forward, adjoint, loss and gradient of a mesh) and `nlos.render` (a simulated capture,
//! as `nlos render` makes it).

use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use nlos_brdf::Model;
use nlos_render::{
    AnyBrdf, DeterministicRule, Device, Kernel, Loss, RenderParams, Renderer as Inner, Sampling, SplatRule, Visibility,
    with_brdf,
};
use nlos_transient::Transient;
use nlos_transient::sensor::{PhotonBudget, SpadModel};

use crate::capture::Capture;
use crate::{arrays, errors};

/// The reflectance model named `brdf` (`nlos_brdf::Model`'s names: "lambert", "ggx", "retroreflective"; and
/// "lambertian", this module's first spelling).
fn model(brdf: &str) -> PyResult<Model> {
    brdf.parse().map_err(|e| PyValueError::new_err(format!("brdf: {e}")))
}

/// `model` with the given parameters ([`AnyBrdf::new`]).
fn any_brdf(model: Model, albedo: f32, specular: f32, alpha: f32) -> PyResult<AnyBrdf> {
    AnyBrdf::new(model, albedo, specular, alpha)
        .map_err(|e| PyValueError::new_err(format!("albedo, specular, alpha of {model}: {e}")))
}

fn kernel(name: &str) -> PyResult<Kernel> {
    match name {
        "box" => Ok(Kernel::Box),
        "tent" => Ok(Kernel::Tent),
        other => Err(PyValueError::new_err(format!("kernel: {other:?} is not \"box\" or \"tent\""))),
    }
}

fn sampling(name: &str) -> PyResult<Sampling> {
    match name {
        "splat" => Ok(Sampling::Splat(SplatRule::default())),
        "exact" => Ok(Sampling::Deterministic(DeterministicRule::default())),
        "fixed" => Ok(Sampling::Deterministic(DeterministicRule::fixed(1))),
        other => Err(PyValueError::new_err(format!("sampling: {other:?} is not \"splat\", \"exact\" or \"fixed\""))),
    }
}

fn visibility(name: &str, level: u32) -> PyResult<Visibility> {
    match name {
        "off" => Ok(Visibility::Off),
        "live" => Ok(Visibility::Live),
        "cached" if (1..=16).contains(&level) => Ok(Visibility::Cached { level }),
        "cached" => Err(PyValueError::new_err(format!("vis_level: {level} is not in 1..=16"))),
        other => Err(PyValueError::new_err(format!("visibility: {other:?} is not \"cached\", \"live\" or \"off\""))),
    }
}

fn device(name: &str) -> PyResult<Device> {
    match name {
        "cpu" => Ok(Device::Cpu),
        "gpu" => Ok(Device::Gpu),
        "auto" => Ok(Device::Auto),
        other => Err(PyValueError::new_err(format!("device: {other:?} is not \"cpu\", \"gpu\" or \"auto\""))),
    }
}

fn matrix(py: Python<'_>, values: Vec<f32>, rows: usize, cols: usize) -> PyResult<Py<PyArray2<f32>>> {
    let array = Array2::from_shape_vec((rows, cols), values).map_err(errors::render)?;
    Ok(PyArray2::from_owned_array(py, array).unbind())
}

/// The differentiable transient renderer of a triangle mesh for one setup (scan and time axis).
///
/// Defaults are the reconstruction loop's: tent kernel, the splat rule, visibility cached per triangle
/// and measurement (level 1), one-sided faces.
#[pyclass(module = "nlos")]
pub(crate) struct Renderer {
    inner: Inner,
    brdf: AnyBrdf,
    vertices: usize,
    measurements: usize,
    bins: usize,
}

#[pymethods]
impl Renderer {
    #[new]
    #[pyo3(signature = (vertices, faces, setup, *, brdf = "lambert", albedo = 1.0, alpha = 0.3, specular = 1.0,
        kernel = "tent", sampling = "splat", visibility = "cached", vis_level = 1, two_sided = false,
        device = "cpu"))]
    #[allow(clippy::too_many_arguments)] // one per Python keyword argument
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        setup: PyRef<'_, Capture>,
        brdf: &str,
        albedo: f32,
        alpha: f32,
        specular: f32,
        kernel: &str,
        sampling: &str,
        visibility: &str,
        vis_level: u32,
        two_sided: bool,
        device: &str,
    ) -> PyResult<Self> {
        let positions = arrays::points("vertices", vertices, None)?;
        let triangles = arrays::faces("faces", faces, positions.len())?;
        let params = RenderParams {
            kernel: self::kernel(kernel)?,
            sampling: self::sampling(sampling)?,
            visibility: self::visibility(visibility, vis_level)?,
            two_sided,
        };
        let brdf = any_brdf(model(brdf)?, albedo, specular, alpha)?;
        let (scan, time) = (setup.scan.clone(), setup.time);
        let device = self::device(device)?;
        let mut inner =
            py.detach(|| Inner::new(&positions, &triangles, &scan, &time, params)).map_err(errors::render)?;
        py.detach(|| inner.set_device(device)).map_err(errors::render)?;
        Ok(Self { inner, brdf, vertices: positions.len(), measurements: scan.measurements(), bins: time.bins })
    }

    /// Moves the vertices (same count, same faces); the visibility cache is kept, as in the loop (call
    /// [`Self::refresh_visibility`] after large moves).
    fn set_vertices(&mut self, vertices: &Bound<'_, PyAny>) -> PyResult<()> {
        let positions = arrays::points("vertices", vertices, Some(self.vertices))?;
        self.inner.set_positions(&positions).map_err(errors::render)
    }

    /// Where forward and adjoint run: `"gpu"` when the renderer uses a GPU, else `"cpu"`.
    #[getter]
    fn device(&self) -> &'static str {
        match self.inner.device() {
            Device::Gpu => "gpu",
            Device::Cpu | Device::Auto => "cpu",
        }
    }

    /// Recomputes the cached visibility at the current vertices (no effect for `visibility="live"` or
    /// `"off"`).
    fn refresh_visibility(&mut self, py: Python<'_>) {
        py.detach(|| self.inner.refresh_visibility());
    }

    /// The BRDF's parameters by name, the keys of the adjoint's gradient dictionary.
    #[getter]
    fn reflectance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (name, value) in self.brdf.param_names().iter().zip(self.brdf.params()) {
            dict.set_item(*name, value)?;
        }
        Ok(dict)
    }

    /// Sets BRDF parameters by name (as the `reflectance` getter and the gradients name them; the others
    /// keep their values), so that a reflectance can be fitted with the adjoint's gradients.
    fn set_reflectance(&mut self, values: &Bound<'_, PyDict>) -> PyResult<()> {
        let names = self.brdf.param_names();
        let mut p = self.brdf.params();
        for (key, value) in values.iter() {
            let key: String = key.extract()?;
            let Some(i) = names.iter().position(|n| *n == key) else {
                return Err(PyValueError::new_err(format!("reflectance: {key:?} is not one of {names:?}")));
            };
            p[i] =
                value.extract().map_err(|_| PyValueError::new_err(format!("reflectance: {key} must be a number")))?;
        }
        self.brdf = self.brdf.with_params(&p).map_err(|e| PyValueError::new_err(format!("reflectance: {e}")))?;
        Ok(())
    }

    /// The rendered transient, measurements × bins, float32 (a new array each call, no further copy).
    fn forward(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f32>>> {
        let brdf = self.brdf;
        let values = py.detach(|| with_brdf!(brdf, b => self.inner.forward(&b)));
        matrix(py, values, self.measurements, self.bins)
    }

    /// Gradients of a loss E through the renderer given `d_loss` = dE/dI (measurements × bins): returns
    /// `(dE/dvertices (n, 3), {BRDF parameter: dE/dparameter})` (Proposition 1 of Tsai et al. 2019).
    fn adjoint<'py>(
        &self,
        py: Python<'py>,
        d_loss: &Bound<'py, PyAny>,
    ) -> PyResult<(Py<PyArray2<f32>>, Bound<'py, PyDict>)> {
        let (d, _) = arrays::floats_2d("d_loss", d_loss, Some(self.measurements), Some(self.bins))?;
        let brdf = self.brdf;
        let g = py.detach(|| with_brdf!(brdf, b => self.inner.adjoint(&b, &d))).map_err(errors::render)?;
        self.gradient_out(py, g)
    }

    /// `(E, dE/dvertices, {parameter: dE/dparameter})` for the loss against `measured` (an array or a
    /// Capture of this setup's shape): `loss="l2"` (½ Σ (I − Ĩ)²) or `"poisson"` (negative log-likelihood).
    #[pyo3(signature = (measured, loss = "l2"))]
    fn loss_and_grad<'py>(
        &self,
        py: Python<'py>,
        measured: &Bound<'py, PyAny>,
        loss: &str,
    ) -> PyResult<(f64, Py<PyArray2<f32>>, Bound<'py, PyDict>)> {
        let loss = match loss {
            "l2" => Loss::L2,
            "poisson" => Loss::PoissonNll { floor: 1e-12 },
            other => return Err(PyValueError::new_err(format!("loss: {other:?} is not \"l2\" or \"poisson\""))),
        };
        let measured = match measured.cast::<Capture>() {
            Ok(c) => c.borrow().data.bind(py).clone().into_any(),
            Err(_) => measured.clone(),
        };
        let (m, _) = arrays::floats_2d("measured", &measured, Some(self.measurements), Some(self.bins))?;
        let brdf = self.brdf;
        let out = py
            .detach(|| with_brdf!(brdf, b => self.inner.loss_and_gradient(&b, &m, loss, None)))
            .map_err(errors::render)?;
        let (dv, dp) = self.gradient_out(py, out.gradient)?;
        Ok((out.loss, dv, dp))
    }

    /// The BRDF's parameter names, in the order of the gradient dictionary.
    #[getter]
    fn brdf_params(&self) -> Vec<&'static str> {
        self.brdf.param_names().to_vec()
    }

    /// `(measurements, bins)` of a rendering.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (self.measurements, self.bins)
    }
}

impl Renderer {
    fn gradient_out<'py>(
        &self,
        py: Python<'py>,
        g: nlos_render::Gradient,
    ) -> PyResult<(Py<PyArray2<f32>>, Bound<'py, PyDict>)> {
        let flat: Vec<f32> = g.vertices.iter().flat_map(|v| v.to_array()).collect();
        let dv = matrix(py, flat, self.vertices, 3)?;
        let dict = PyDict::new(py);
        for (name, value) in self.brdf.param_names().iter().zip(&g.brdf) {
            dict.set_item(*name, *value)?;
        }
        Ok((dv, dict))
    }
}

/// A simulated capture of a mesh, as `nlos render` makes it: box kernel (a measurement integrates its
/// bin), the box kernel's closed form (`Sampling::Splat`), visibility cached at level 1 (or as given), Lambertian albedo 1 or GGX
/// (`alpha`); with `photons`, SPAD photon counts (Poisson, expected `photons` per measurement, `seed`).
#[pyfunction]
#[pyo3(signature = (vertices, faces, setup = None, *, brdf = "lambert", alpha = 0.3, visibility = "cached",
    vis_level = 1, two_sided = false, photons = None, seed = 0))]
#[allow(clippy::too_many_arguments)] // one per Python keyword argument
pub(crate) fn render(
    py: Python<'_>,
    vertices: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
    setup: Option<PyRef<'_, Capture>>,
    brdf: &str,
    alpha: f32,
    visibility: &str,
    vis_level: u32,
    two_sided: bool,
    photons: Option<f64>,
    seed: u64,
) -> PyResult<Capture> {
    let positions = arrays::points("vertices", vertices, None)?;
    let triangles = arrays::faces("faces", faces, positions.len())?;
    let (scan, time) = match &setup {
        Some(s) => (s.scan.clone(), s.time),
        None => {
            let s = crate::capture::confocal_setup(py, 64, 0.25, 1200, 0.0012, 0.0)?;
            (s.scan, s.time)
        }
    };
    let params = RenderParams {
        kernel: Kernel::Box,
        sampling: Sampling::Splat(SplatRule::default()),
        visibility: self::visibility(visibility, vis_level)?,
        two_sided,
    };
    // `nlos render`'s surface: albedo 1, GGX's specular lobe alone.
    let brdf = AnyBrdf::unit(model(brdf)?, alpha).map_err(|e| PyValueError::new_err(format!("alpha: {e}")))?;
    let model = match photons {
        Some(n) if !(n.is_finite() && n > 0.0) => {
            return Err(PyValueError::new_err(format!("photons: {n} must be finite and > 0")));
        }
        Some(n) => Some(SpadModel::ideal(PhotonBudget::PerMeasurement(n))),
        None => None,
    };
    let out: Transient = py
        .detach(|| -> Result<Transient, String> {
            let r = Inner::new(&positions, &triangles, &scan, &time, params).map_err(|e| e.to_string())?;
            let clean = with_brdf!(brdf, b => r.forward_transient(&b)).map_err(|e| e.to_string())?;
            match &model {
                Some(m) => m.simulate(&clean, seed).map_err(|e| e.to_string()),
                None => Ok(clean),
            }
        })
        .map_err(errors::render)?;
    Capture::new(py, out, None)
}
