//! The splat rule on a GPU (feature `gpu`): [`GpuRenderer`] runs [`Renderer::forward`] and
//! [`Renderer::adjoint`] of a [`Renderer`] through wgpu compute shaders (Vulkan, Metal, DX12), term for term the
//! arithmetic of the CPU's splat kernels (`shader.wgsl` names the functions it follows).
//!
//! What it covers: [`Sampling::Splat`] with the tent kernel (the optimiser's rule), visibility
//! [`Visibility::Off`] or [`Visibility::Cached`] (the cache is computed on the CPU and uploaded when it changes),
//! one- or two-sided faces, per-face weights, confocal and general scans, and the BRDFs with the shader's terms
//! (`brdf::gpu_terms`: Lambertian, retroreflective); [`crate::gpu_support`] says so. Anything else is a
//! [`RenderError::Gpu`] naming what to change.
//!
//! Deterministic: the forward pass sums each bin in 64-bit fixed point (integer atomics, so the order of the
//! additions does not matter), the adjoint gives every (triangle, range of measurements) its own sums and adds
//! the ranges in order, and the vertex distribution is the CPU's. The same device gives the same bits on every
//! run; another GPU (or the CPU) agrees to f32 rounding (`tests/gpu.rs`: 1e-4 of the transient's peak).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use bytemuck::{Pod, Zeroable};
use nlos_brdf::{AnyBrdf, FittedBrdf, Model};

use crate::brdf::{GpuTerms, gpu_terms};
use crate::error::Result;
use crate::render::backend::Backend;
use crate::render::scene::Scene;
use crate::{Device, Gradient, RenderError, RenderParams, Renderer, Visibility};

/// Threads of a workgroup (the shader's `WG`).
const WG: u32 = 256;
/// Adjoint: about this many threads in flight, as (triangle, range of measurements) pairs.
const ADJOINT_THREADS: usize = 1 << 18;
/// Measurements per row of the forward dispatch (the grid's z dimension counts the rows).
const M_ROW: u32 = 32_768;

/// The shader's `Params` (uniform, 64 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Params {
    nt: u32,
    nm: u32,
    bins: u32,
    confocal: u32,
    two_sided: u32,
    brdf: u32,
    has_vis: u32,
    chunk: u32,
    albedo: f32,
    inv_w2: f32,
    t0: f32,
    inv_dt: f32,
    power: f32,
    max_contrib: f32,
    pad: [f32; 2],
}

/// Pipelines compiled for one histogram capacity (bins per forward workgroup).
#[derive(Debug)]
struct Pipelines {
    hb: u32,
    forward: wgpu::ComputePipeline,
    adjoint: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
}

/// The device's copy of the visibility cache and which refresh it holds (unique in the process).
#[derive(Debug)]
struct VisCopy {
    buffer: wgpu::Buffer,
    key: (u64, usize),
}

/// A GPU (wgpu adapter, device and queue) and the splat rule's compute pipelines. One `GpuRenderer` serves any
/// number of [`Renderer`]s, one call at a time; it uploads the geometry on every call and the visibility cache
/// when it changed.
///
/// ```no_run
/// # use nlos_render::{GpuRenderer, Renderer, RenderParams, Sampling, SplatRule, Visibility};
/// # fn demo(r: &Renderer, brdf: &nlos_brdf::Lambertian<f32>) -> nlos_render::Result<()> {
/// let mut gpu = GpuRenderer::new()?; // RenderError::Gpu when the machine has no adapter
/// let transient = gpu.forward(r, brdf)?;
/// let grad = gpu.adjoint(r, brdf, &vec![1.0; transient.len()])?;
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct GpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: String,
    /// Whether the adapter is a hardware GPU (not a software one such as lavapipe).
    hardware: bool,
    limits: wgpu::Limits,
    layout: wgpu::BindGroupLayout,
    pipelines: Option<Pipelines>,
    vis: Option<VisCopy>,
}

fn gpu_err(reason: impl Into<String>) -> RenderError {
    RenderError::Gpu(reason.into())
}

impl GpuRenderer {
    /// Opens the first high-performance adapter wgpu finds (Vulkan, Metal or DX12; `WGPU_BACKEND` and
    /// `WGPU_ADAPTER_NAME` choose among several), with the adapter's own limits.
    ///
    /// # Errors
    /// [`RenderError::Gpu`] when no adapter is found (no GPU, or no Vulkan driver: on Linux install the
    /// vendor's driver or Mesa's `mesa-vulkan-drivers`) or the device cannot be opened.
    pub fn new() -> Result<Self> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::PRIMARY;
        }
        let instance = wgpu::Instance::new(desc);
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        };
        let adapter = pollster::block_on(instance.request_adapter(&options)).map_err(|e| {
            gpu_err(format!(
                "no GPU adapter found ({e}); install a Vulkan driver (the vendor's, or Mesa's mesa-vulkan-drivers \
                 for a software one) or run on the CPU"
            ))
        })?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("nlos-render"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| gpu_err(format!("the adapter {} refused a device: {e}", info.name)))?;
        // Every call runs inside error scopes (`Scopes`); an error outside them is reported, never a panic.
        device.on_uncaptured_error(Arc::new(|e| eprintln!("warning: GPU backend: {e}")));
        let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("nlos-render splat"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1, true),
                storage(2, true),
                storage(3, true),
                storage(4, false),
                storage(5, false),
                storage(6, false),
            ],
        });
        Ok(Self {
            device,
            queue,
            adapter: format!("{} ({:?}, {})", info.name, info.backend, info.driver),
            hardware: info.device_type != wgpu::DeviceType::Cpu,
            limits,
            layout,
            pipelines: None,
            vis: None,
        })
    }

    /// The adapter: name, backend and driver.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// Whether the adapter is a hardware GPU (false for a software rasteriser such as Mesa's lavapipe).
    pub fn is_hardware(&self) -> bool {
        self.hardware
    }

    /// The forward pass of `r` on the GPU: the transient, measurement-major, as [`Renderer::forward`] gives it
    /// (to f32 rounding).
    ///
    /// # Errors
    /// [`RenderError::Gpu`] when the renderer's settings or the BRDF have no GPU version, a buffer exceeds the
    /// device's limits, or the device fails.
    pub fn forward<B: FittedBrdf>(&mut self, r: &Renderer, brdf: &B) -> Result<Vec<f32>> {
        self.forward_scene(&r.scene, brdf)
    }

    /// [`GpuRenderer::forward`] of a scene.
    fn forward_scene<B: FittedBrdf>(&mut self, r: &Scene, brdf: &B) -> Result<Vec<f32>> {
        let setup = self.prepare(r, brdf)?;
        let nm = r.wall.l.len();
        let bins = r.time.bins;
        let out_len = nm * bins;
        let rows = self.storage("transient", (out_len * 4) as u64)?;
        let hb = setup.params.bins.min(self.pipelines.as_ref().map_or(1, |p| p.hb));
        let bin_chunks = (bins as u32).div_ceil(hb);
        let scopes = Scopes::push(&self.device);
        let bind = self.bind(&setup, &rows, None, None)?;
        let mut enc = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
            pass.set_pipeline(&self.pipes()?.forward);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((nm as u32).min(M_ROW), bin_chunks, (nm as u32).div_ceil(M_ROW));
        }
        let out = self.read(enc, &rows, out_len);
        scopes.check()?;
        out
    }

    /// The adjoint pass of `r` on the GPU: dE/d(vertices), dE/d(BRDF parameters) and dE/d(face weights) for the
    /// adjoint rows `d_loss` (`dE/dI`, measurement-major), as [`Renderer::adjoint`] gives them (to f32 rounding).
    ///
    /// # Errors
    /// [`RenderError::LengthMismatch`] when `d_loss` is not one value per (measurement, bin); otherwise as
    /// [`GpuRenderer::forward`].
    pub fn adjoint<B: FittedBrdf>(&mut self, r: &Renderer, brdf: &B, d_loss: &[f32]) -> Result<Gradient> {
        self.adjoint_scene(&r.scene, brdf, d_loss)
    }

    /// [`GpuRenderer::adjoint`] of a scene.
    fn adjoint_scene<B: FittedBrdf>(&mut self, r: &Scene, brdf: &B, d_loss: &[f32]) -> Result<Gradient> {
        let nm = r.wall.l.len();
        let expected = nm * r.time.bins;
        if d_loss.len() != expected {
            return Err(RenderError::LengthMismatch { what: "d_loss", expected, got: d_loss.len() });
        }
        let mut setup = self.prepare(r, brdf)?;
        let nt = r.tris.v0.len();
        // At most 65,535 ranges: the grid's y dimension.
        let ranges = ADJOINT_THREADS.div_ceil(nt.max(1)).clamp(1, nm.min(65_535));
        let chunk = nm.div_ceil(ranges);
        let ranges = nm.div_ceil(chunk);
        setup.params.chunk = chunk as u32;
        let rows = self.storage("adjoint rows", (expected * 4).max(4) as u64)?;
        self.queue.write_buffer(&rows, 0, bytemuck::cast_slice(d_loss));
        let partial = self.storage("adjoint partial sums", (ranges * nt * 64).max(4) as u64)?;
        let sums = self.storage("adjoint sums", (nt * 64).max(4) as u64)?;
        if nt == 0 {
            return Ok(r.distribute::<B>(&[], [0.0; 4]));
        }
        let scopes = Scopes::push(&self.device);
        let bind = self.bind(&setup, &rows, Some(&partial), Some(&sums))?;
        let mut enc = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let pipes = self.pipes()?;
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
            pass.set_bind_group(0, &bind, &[]);
            pass.set_pipeline(&pipes.adjoint);
            pass.dispatch_workgroups((nt as u32).div_ceil(WG), ranges as u32, 1);
            pass.set_pipeline(&pipes.reduce);
            pass.dispatch_workgroups((16 * nt as u32).div_ceil(WG), 1, 1);
        }
        let flat = self.read(enc, &sums, 16 * nt);
        scopes.check()?;
        let flat = flat?;
        let mut per_tri = vec![[0.0f64; 12]; nt];
        let mut dp = [0.0f64; 4];
        for (o, s) in per_tri.iter_mut().zip(flat.chunks_exact(16)) {
            for (x, y) in o.iter_mut().zip(s) {
                *x = f64::from(*y);
            }
            for (p, y) in dp.iter_mut().zip(&s[12..]) {
                *p += f64::from(*y);
            }
        }
        Ok(r.distribute::<B>(&per_tri, dp))
    }

    fn pipes(&self) -> Result<&Pipelines> {
        self.pipelines.as_ref().ok_or_else(|| gpu_err("internal: pipelines not built"))
    }

    /// Checks what `r` asks for, uploads its triangles, wall and visibility, and builds the pipelines.
    fn prepare<B: FittedBrdf>(&mut self, r: &Scene, brdf: &B) -> Result<Setup> {
        super::gpu_support(B::MODEL, &r.params).map_err(RenderError::Gpu)?;
        let axis = r.splat_axis(&r.kernel).ok_or_else(|| gpu_err("internal: the splat rule without a tent axis"))?;
        let has_vis = matches!(r.params.visibility, Visibility::Cached { .. });
        let GpuTerms { kind: brdf_kind, albedo, inv_w2 } =
            gpu_terms(&brdf.to_any()).ok_or_else(|| gpu_err("internal: a model gpu_support accepts without terms"))?;
        let (nt, nm, bins) = (r.tris.v0.len(), r.wall.l.len(), r.time.bins);
        if has_vis && (nt as u64) * (nm as u64) >= u64::from(u32::MAX) {
            return Err(gpu_err(format!(
                "{nt} triangles × {nm} measurements of cached visibility exceed the shader's 32-bit index"
            )));
        }
        // The reduction's grid: 16 values per triangle, 256 per workgroup, at most 65,535 workgroups.
        if nt > 65_535 * (WG as usize / 16) {
            return Err(gpu_err(format!("{nt} triangles exceed the GPU backend's 1,048,560; render on the CPU")));
        }
        let max_level = r.tri_levels.iter().copied().max().unwrap_or(1);
        let params = Params {
            nt: nt as u32,
            nm: nm as u32,
            bins: bins as u32,
            confocal: u32::from(r.wall.confocal),
            two_sided: u32::from(r.params.two_sided),
            brdf: brdf_kind,
            has_vis: u32::from(has_vis),
            chunk: 1,
            albedo,
            inv_w2,
            t0: axis.t0,
            inv_dt: axis.inv_dt,
            power: B::DISTANCE_POWER,
            max_contrib: (nt.max(1) as f32) * (max_level * max_level) as f32,
            pad: [0.0; 2],
        };
        self.build_pipelines(bins as u32)?;
        // Triangles in storage-slot order (the visibility cache's order): [v0, level], [e1, 1/(2|N|)],
        // [e2, 1/|N|²], [N, weight] with weight 0 for a degenerate face.
        let mut tris = Vec::with_capacity(nt * 16);
        for slot in 0..nt {
            let t = r.mesh_triangle(slot);
            let (n, valid) = (r.tris.n[t], r.tris.valid[t]);
            let len2 = n.length_squared();
            let level = r.tri_levels.get(t).copied().unwrap_or(1);
            let w = if valid { r.face_weight(t) } else { 0.0 };
            let (inv_2n, inv_n2) = if valid { (0.5 / len2.sqrt(), 1.0 / len2) } else { (0.0, 0.0) };
            let (v0, e1, e2) = (r.tris.v0[t], r.tris.e1[t], r.tris.e2[t]);
            // The level as a float (exact: at most 64), not its bits, which would be a subnormal a GPU may flush.
            tris.extend_from_slice(&[v0.x, v0.y, v0.z, level as f32]);
            tris.extend_from_slice(&[e1.x, e1.y, e1.z, inv_2n, e2.x, e2.y, e2.z, inv_n2, n.x, n.y, n.z, w]);
        }
        let mut wall = Vec::with_capacity(nm * 16);
        for m in 0..nm {
            for v in [r.wall.l[m], r.wall.n_l[m], r.wall.s[m], r.wall.n_s[m]] {
                wall.extend_from_slice(&[v.x, v.y, v.z, 0.0]);
            }
        }
        let tris_buf = self.upload("triangles", &tris)?;
        let wall_buf = self.upload("wall", &wall)?;
        if has_vis {
            self.upload_visibility(r)?;
        }
        let uniform = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: 64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let dummy = self.storage("no visibility", 4)?;
        Ok(Setup { params, uniform, tris: tris_buf, wall: wall_buf, dummy, has_vis })
    }

    /// Compiles the pipelines for a histogram capacity of `bins` (capped by the device's workgroup memory).
    fn build_pipelines(&mut self, bins: u32) -> Result<()> {
        // Two u32 words per bin, and a few words of the shader's own.
        let cap = (self.limits.max_compute_workgroup_storage_size.saturating_sub(64) / 8).max(1);
        let hb = bins.clamp(1, cap);
        if self.pipelines.as_ref().is_some_and(|p| p.hb == hb) {
            return Ok(());
        }
        let scopes = Scopes::push(&self.device);
        let module = self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("shader.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        // The histogram capacity, the shader's overridable `HB`.
        let constants = [("HB", f64::from(hb))];
        let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: &[Some(&self.layout)],
            immediate_size: 0,
        });
        let make = |entry: &str| {
            self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..wgpu::PipelineCompilationOptions::default()
                },
                cache: None,
            })
        };
        let pipelines = Pipelines { hb, forward: make("forward"), adjoint: make("adjoint"), reduce: make("reduce") };
        scopes.check()?;
        self.pipelines = Some(pipelines);
        Ok(())
    }

    /// Uploads the renderer's visibility cache (as words of four bytes) unless the device holds this refresh.
    fn upload_visibility(&mut self, r: &Scene) -> Result<()> {
        let Some(cache) = &r.cache else {
            return Err(gpu_err("Visibility::Cached without a cache: call Renderer::refresh_visibility"));
        };
        let key = (r.vis_generation, cache.len());
        if self.vis.as_ref().is_some_and(|v| v.key == key) {
            return Ok(());
        }
        // The shader reads the cache measurement-major (entry m · triangles + slot).
        let words: Vec<u32> = r
            .cache_layout()
            .measurement_major(cache)
            .chunks(4)
            .map(|c| c.iter().enumerate().fold(0u32, |w, (i, b)| w | (u32::from(*b) << (8 * i))))
            .collect();
        let buffer = self.upload("visibility", &words)?;
        self.vis = Some(VisCopy { buffer, key });
        Ok(())
    }

    fn check_size(&self, what: &str, size: u64) -> Result<()> {
        let max = self.limits.max_storage_buffer_binding_size.min(self.limits.max_buffer_size);
        if size > max {
            return Err(gpu_err(format!(
                "the {what} need {size} bytes, more than the device binds ({max}); use fewer measurements or bins"
            )));
        }
        Ok(())
    }

    fn storage(&self, what: &str, size: u64) -> Result<wgpu::Buffer> {
        self.check_size(what, size)?;
        Ok(self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(what),
            size: size.next_multiple_of(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        }))
    }

    fn upload<T: Pod>(&self, what: &str, data: &[T]) -> Result<wgpu::Buffer> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let buf = self.storage(what, (bytes.len() as u64).max(4))?;
        if !bytes.is_empty() {
            self.queue.write_buffer(&buf, 0, bytes);
        }
        Ok(buf)
    }

    fn bind(
        &self,
        s: &Setup,
        rows: &wgpu::Buffer,
        partial: Option<&wgpu::Buffer>,
        sums: Option<&wgpu::Buffer>,
    ) -> Result<wgpu::BindGroup> {
        self.queue.write_buffer(&s.uniform, 0, bytemuck::bytes_of(&s.params));
        let vis = match (&self.vis, s.has_vis) {
            (Some(v), true) => &v.buffer,
            _ => &s.dummy,
        };
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        // Bindings a pass does not use get a one-word stand-in (they must be distinct from the writable ones).
        let (spare5, spare6) = (self.storage("unused", 4)?, self.storage("unused", 4)?);
        let (p5, p6) = (partial.unwrap_or(&spare5), sums.unwrap_or(&spare6));
        Ok(self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.layout,
            entries: &[
                entry(0, &s.uniform),
                entry(1, &s.tris),
                entry(2, &s.wall),
                entry(3, vis),
                entry(4, rows),
                entry(5, p5),
                entry(6, p6),
            ],
        }))
    }

    /// Submits `enc` with a copy of `len` f32 of `src` into a mapped buffer, waits, and returns them.
    fn read(&self, mut enc: wgpu::CommandEncoder, src: &wgpu::Buffer, len: usize) -> Result<Vec<f32>> {
        let size = (len as u64 * 4).max(4);
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        enc.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        self.queue.submit([enc.finish()]);
        let status: Arc<Mutex<Option<std::result::Result<(), wgpu::BufferAsyncError>>>> = Arc::default();
        let done = Arc::clone(&status);
        staging.map_async(wgpu::MapMode::Read, .., move |res| {
            if let Ok(mut s) = done.lock() {
                *s = Some(res);
            }
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| gpu_err(format!("waiting for the device failed: {e}")))?;
        match status.lock().map(|s| s.clone()) {
            Ok(Some(Ok(()))) => {}
            Ok(Some(Err(e))) => return Err(gpu_err(format!("reading the results back failed: {e}"))),
            _ => return Err(gpu_err("the device did not finish reading the results back")),
        }
        let view = staging.get_mapped_range(..).map_err(|e| gpu_err(format!("mapping the results failed: {e}")))?;
        let out = bytemuck::cast_slice::<u8, f32>(&view)[..len].to_vec();
        drop(view);
        staging.unmap();
        Ok(out)
    }
}

/// What one call binds.
#[derive(Debug)]
struct Setup {
    params: Params,
    uniform: wgpu::Buffer,
    tris: wgpu::Buffer,
    wall: wgpu::Buffer,
    dummy: wgpu::Buffer,
    has_vis: bool,
}

/// Validation and out-of-memory error scopes around one call: its errors come back as [`RenderError::Gpu`].
struct Scopes {
    validation: wgpu::ErrorScopeGuard,
    memory: wgpu::ErrorScopeGuard,
}

impl Scopes {
    fn push(device: &wgpu::Device) -> Self {
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        Self { validation, memory }
    }

    /// Pops both (innermost first) and returns the first error either caught.
    fn check(self) -> Result<()> {
        let memory = pollster::block_on(self.memory.pop());
        let validation = pollster::block_on(self.validation.pop());
        match memory.or(validation) {
            None => Ok(()),
            Some(e) => Err(gpu_err(format!("the device reported: {e}"))),
        }
    }
}

/// The process's GPU and whether it is a hardware one, or why there is none.
type Shared = std::result::Result<(Arc<Mutex<GpuRenderer>>, bool), String>;

/// The process's GPU, opened on first use ([`Renderer::set_device`]); the error where there is none.
fn shared() -> Shared {
    static SHARED: OnceLock<Shared> = OnceLock::new();
    SHARED
        .get_or_init(|| {
            GpuRenderer::new()
                .map(|g| {
                    let hardware = g.hardware;
                    (Arc::new(Mutex::new(g)), hardware)
                })
                .map_err(|e| e.to_string())
        })
        .clone()
}

/// Where a renderer with settings `p` runs for `render.device = "gpu"` (`required`) or `"auto"`, and why
/// ([`super::describe_device`]).
pub(super) fn describe(required: bool, p: &RenderParams) -> String {
    let name = |g: &Arc<Mutex<GpuRenderer>>| g.lock().map_or_else(|_| "a GPU".to_string(), |g| g.adapter.clone());
    match required {
        true => match (super::gpu_settings(p), shared()) {
            (Err(why), _) => format!("none: render.device = \"gpu\", but {why}"),
            (Ok(()), Err(e)) => format!("none: render.device = \"gpu\", but {e}"),
            (Ok(()), Ok((g, _))) => format!("the GPU {} (render.device = \"gpu\")", name(&g)),
        },
        false => match (super::gpu_settings(p), shared()) {
            (Err(why), _) => format!("the CPU (render.device = \"auto\": {why})"),
            (Ok(()), Err(e)) => format!("the CPU (render.device = \"auto\": {e})"),
            (Ok(()), Ok((g, false))) => format!(
                "the CPU (render.device = \"auto\": the only GPU adapter, {}, is a software one; \"gpu\" uses it)",
                name(&g)
            ),
            (Ok(()), Ok((g, true))) => format!("the GPU {} (render.device = \"auto\": a hardware GPU)", name(&g)),
        },
    }
}

/// Turns off Mesa's Vulkan device-selection layer (`VK_LAYER_MESA_device_select`, through its own switch
/// `NODEVICE_SELECT=1`) on a machine without a display session (`XDG_RUNTIME_DIR` not a directory). Looking
/// for a GPU there loads the layer, which connects to Wayland to find the display's GPU and prints
/// `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` to stderr although nothing failed;
/// without a display it has nothing to choose by. A value the user set is kept.
///
/// # Safety
/// Changes the process's environment ([`std::env::set_var`]): call it before any other thread can read the
/// environment, as at the top of `main`.
#[allow(unsafe_code)] // `std::env::set_var` is unsafe; the contract is the caller's (above)
pub(super) unsafe fn silence_display_probe() {
    let display_session = std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir());
    if !display_session && std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: the caller's contract: no other thread reads or writes the environment now.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

/// The GPU backend: a renderer's handle on the process's shared GPU. A device error sends the renderer to
/// the CPU for good (reported once).
#[derive(Debug)]
pub(crate) struct GpuBackend {
    gpu: Arc<Mutex<GpuRenderer>>,
    failed: AtomicBool,
}

/// The GPU for `device` and settings `p` (None: the CPU).
pub(super) fn attach(device: Device, p: &RenderParams) -> Result<Option<GpuBackend>> {
    let wrap = |gpu| Some(GpuBackend { gpu, failed: AtomicBool::new(false) });
    match device {
        Device::Cpu => Ok(None),
        Device::Auto => Ok(match (super::gpu_settings(p), shared()) {
            (Ok(()), Ok((gpu, true))) => wrap(gpu),
            _ => None,
        }),
        Device::Gpu => {
            super::gpu_settings(p).map_err(RenderError::Gpu)?;
            let (gpu, _) = shared().map_err(|e| RenderError::Gpu(e.trim_start_matches("GPU backend: ").to_string()))?;
            Ok(wrap(gpu))
        }
    }
}

impl GpuBackend {
    /// Runs `f` on the shared GPU, locked for one pass. A failure is reported once on stderr and sends this
    /// renderer to the CPU for good ([`Backend::supports`] refuses from then on).
    fn locked<T>(&self, f: impl FnOnce(&mut GpuRenderer) -> Result<T>) -> Result<T> {
        let out = match self.gpu.lock() {
            Ok(mut g) => f(&mut g),
            Err(_) => Err(gpu_err("the device's lock was poisoned by a panic")),
        };
        if let Err(e) = &out
            && !self.failed.swap(true, Ordering::Relaxed)
        {
            eprintln!("warning: {e}; this renderer continues on the CPU");
        }
        out
    }
}

impl Backend for GpuBackend {
    fn device(&self) -> Device {
        Device::Gpu
    }

    fn supports(&self, model: Model, params: &RenderParams) -> std::result::Result<(), String> {
        if self.failed.load(Ordering::Relaxed) {
            return Err("the GPU failed before in this renderer".into());
        }
        crate::gpu_support(model, params)
    }

    fn forward(&self, scene: &Scene, brdf: &AnyBrdf) -> Result<Vec<f32>> {
        nlos_brdf::with_brdf!(brdf, b => self.locked(|g| g.forward_scene(scene, b)))
    }

    fn adjoint(&self, scene: &Scene, brdf: &AnyBrdf, d_loss: &[f32]) -> Result<Gradient> {
        nlos_brdf::with_brdf!(brdf, b => self.locked(|g| g.adjoint_scene(scene, b, d_loss)))
    }
}
