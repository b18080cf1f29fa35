//! The steps of one block of the loop ([`super::run`]), as the module doc names them: the shape block
//! (with the collision-aware evolution of its displacement), the reflectance block, pruning and residual
//! patches, and the bookkeeping; what the block's end decides (relative decrease, time budget) and whether
//! the next stage starts are the planner's ([`super::plan`]).

use std::sync::RwLock;
use std::time::Instant;

use glam::Vec3;
use nlos_mesh::SurfaceMesh;
use nlos_render::Renderer;
use nlos_transient::Transient;

use super::evaluation::{Attempt, Fit, evaluate, row_terms};
use super::plan::{BlockEnd, Next, Plan};
use super::record::RunRecord;
use super::rollback::{GoodReflectance, GoodShape, rollback, rollback_refl};
use super::topology::{collision_step, drop_faces, untangle};
use super::{
    Evolve, EvolveRecord, Hooks, IntersectionCheck, IterationRecord, ProgressEvent, SHAPE_MOMENTS, StepKind, progress,
    report, set_albedo_weights,
};
use crate::albedo;
use crate::boundary_smoothing::BoundarySmoothing;
use crate::data_term::RowLoss;
use crate::error::{OptimError, Result};
use crate::params::ReconstructParams;
use crate::prune::{PruneRecord, prune_boundary};
use crate::regions::{RegionFit, RegionNoise, RegionRecord, dark_regions};
use crate::regularizer::{NormalSmoothing, auto_weight};
use crate::residual::{PatchFit, PatchNote, ResidualRecord, residual_rounds};
use crate::surface::Remap;

/// What every block of a run shares: its settings and what was decided from them once.
pub(super) struct RunCtx<'a> {
    pub(super) params: &'a ReconstructParams,
    /// Photon counts (a sensor fit, or a data term told so): the regulariser weight discounts the noise floor.
    pub(super) counts: bool,
    /// θ of the BRDF is fitted in the reflectance blocks.
    pub(super) fit_brdf: bool,
    /// Steps of a reflectance block (0: none).
    pub(super) refl_iters: u32,
    /// Iterations the schedule allows (the progress bar's length).
    pub(super) planned: u64,
    /// The budget planner: stage edges, whether blocks and stages fit, when the run stops.
    pub(super) plan: Plan,
    start: Instant,
    /// Run time before this process's part of the run (a resumed run's earlier time).
    t_base: f64,
}

impl<'a> RunCtx<'a> {
    pub(super) fn new(st: &RunRecord, params: &'a ReconstructParams, plan: Plan) -> Self {
        let sch = params.schedule;
        // A Lambertian (or retroreflective) albedo is a pure scale factor: with the scale solved in closed form
        // its gradient is zero, and a reflectance block would spend full forward/adjoint renders to leave θ
        // where it is.
        let scale_only = st.reflectance.is_scale_only() && params.data.solve_scale;
        let fit_brdf = !scale_only && !st.reflectance.theta().is_empty();
        // The per-vertex albedo (crate::albedo) steps with the shape: it needs no reflectance block of its own.
        let refl_iters = if fit_brdf { sch.reflectance_iterations } else { 0 };
        let planned = u64::from(sch.max_stages)
            * u64::from(sch.max_blocks_per_stage)
            * u64::from(sch.shape_iterations + refl_iters);
        Self {
            params,
            counts: params.sensor.is_some() || params.data.counts,
            fit_brdf,
            refl_iters,
            planned,
            plan,
            start: Instant::now(),
            t_base: st.elapsed_s,
        }
    }

    /// Seconds the run has taken, resumed parts included.
    pub(super) fn elapsed(&self) -> f64 {
        self.t_base + self.start.elapsed().as_secs_f64()
    }
}

/// A block's working set: the stage's capture and data term, and the renderer and regularisers of the
/// block's topology.
pub(super) struct Block<'a> {
    /// The stage's target edge length, metres.
    pub(super) target: f64,
    /// The stage's capture (its bins summed, [`crate::Schedule::rebin`]).
    pub(super) measured: &'a Transient,
    pub(super) fit: Fit<'a>,
    pub(super) renderer: Renderer,
    pub(super) reg: NormalSmoothing,
    pub(super) edge_reg: BoundarySmoothing,
    /// Boundary flags per vertex (their own learning rate).
    pub(super) boundary: Vec<bool>,
    /// What collision handling did in this block (its remeshing's refusals, its steps' limits).
    pub(super) collisions: EvolveRecord,
    /// The loss at the block's first step and at its last.
    pub(super) first: f64,
    pub(super) last: f64,
    /// Weight of the albedo's total variation (crate::albedo, "Prior"), set at the block's first step.
    pub(super) tv_weight: f64,
}

/// Step 2: the shape block — `schedule.shape_iterations` Adam steps on the vertices, each through the
/// caller's `evolve` hook (if any) and then collision-aware evolution ([`ReconstructParams::collision`]:
/// no step makes the surface intersect itself), rolled back on a non-finite loss, gradient or position.
pub(super) fn shape_block<'e>(
    st: &mut RunRecord,
    ctx: &RunCtx<'_>,
    b: &mut Block<'_>,
    hooks: &mut Hooks<'_>,
    mut evolve: Option<&mut (dyn Evolve + 'e)>,
) -> Result<()> {
    let params = ctx.params;
    let w_edge = params.boundary_smoothing;
    let mut good: Option<GoodShape> = None;
    let mut it = 0;
    while it < params.schedule.shape_iterations {
        let attempt = (|| -> Result<Option<Attempt>> {
            let ev = evaluate(st, &b.renderer, &b.fit, ctx.counts)?;
            let (r_n, mut rg) = b.reg.evaluate(st.surface.positions(), st.surface.triangles())?;
            let mut r = r_n;
            if w_edge > 0.0 {
                let (r_e, eg) = b.edge_reg.evaluate(st.surface.positions())?;
                r += w_edge * r_e;
                for (g, e) in rg.iter_mut().zip(&eg) {
                    *g += w_edge as f32 * *e;
                }
            }
            let ok = ev.data.is_finite() && r.is_finite() && ev.grad_vertices.iter().all(|g| g.is_finite());
            Ok(ok.then_some((ev, r, r_n, rg)))
        })()?;
        let Some((ev, r, r_n, rg)) = attempt else {
            rollback(st, &mut good, &mut b.renderer, params, "loss or gradient")?;
            continue;
        };
        if it == 0 {
            let area = st.surface.area();
            // With counts, the regulariser is weighed against the part of the data term above its noise
            // floor (crate::data_term::counts, "Noise floor"; DataTerm::noise_floor); at least 1 % of the data term,
            // so a fit that has reached the floor keeps some smoothing.
            let excess = if ctx.counts { (ev.data - ev.floor).max(0.01 * ev.data) } else { ev.data };
            st.reg_weight =
                params.regulariser_weight.unwrap_or_else(|| auto_weight(params.regulariser_ratio, excess, r_n, area));
            b.tv_weight = params.albedo.map_or(0.0, |a| a.tv * excess);
        }
        let lam = st.reg_weight;
        let loss = ev.data + lam * r;
        if it == 0 {
            b.first = loss;
        }
        b.last = loss;
        st.scale = ev.scale;
        let step = params.lr_interior * b.target * st.lr_scale;
        st.log.iterations.push(IterationRecord {
            iteration: st.iteration,
            stage: st.stage,
            block: st.block_in_stage,
            kind: StepKind::Shape,
            loss,
            data: ev.data,
            regulariser: r,
            reg_weight: lam,
            scale: ev.scale,
            step_size: step,
            faces: st.surface.n_faces(),
            vertices: st.surface.n_vertices(),
            time_s: ctx.elapsed(),
            noise_floor: ctx.counts.then_some(ev.floor),
        });
        let _ = report(hooks, &progress(st, ProgressEvent::Iteration, ctx.planned, loss, b.target, ctx.elapsed()));
        let grad: Vec<Vec3> = ev.grad_vertices.iter().zip(&rg).map(|(g, q)| *g + lam as f32 * *q).collect();
        good = Some((st.surface.clone(), st.shape_adam, st.albedo_steps));
        let (li, lb) = (params.lr_interior * b.target * st.lr_scale, params.lr_boundary * b.target * st.lr_scale);
        let boundary = &b.boundary;
        let moments = st.surface.vertex_mut(SHAPE_MOMENTS)?;
        let disp = st.shape_adam.step(&params.shape_adam, moments, &grad, |i| if boundary[i] { lb } else { li });
        let surface = &st.surface;
        let proposed = match evolve.as_deref_mut() {
            Some(hook) => Some(hook.evolve(surface.positions(), surface.triangles(), &disp)?),
            None => None,
        };
        if proposed.as_ref().is_some_and(|p| p.len() != surface.n_vertices() || p.iter().any(|p| !p.is_finite())) {
            rollback(st, &mut good, &mut b.renderer, params, "positions")?;
            continue;
        }
        let new = match (proposed, params.collision) {
            (Some(p), None) => p,
            (None, None) => surface.positions().iter().zip(&disp).map(|(p, d)| *p + *d).collect(),
            (proposed, Some(ep)) => {
                let d = match proposed {
                    Some(p) => p.iter().zip(surface.positions()).map(|(p, q)| *p - *q).collect(),
                    None => disp,
                };
                collision_step(surface, &d, b.target as f32, ep, &mut b.collisions)?
            }
        };
        if new.iter().any(|p| !p.is_finite()) {
            rollback(st, &mut good, &mut b.renderer, params, "positions")?;
            continue;
        }
        // The albedo from the same rendering (crate::albedo, "Steps"), at the positions it was rendered at.
        if params.albedo.is_some() {
            albedo_step(st, params, b.tv_weight, &ev.grad_faces)?;
            set_albedo_weights(st, &mut b.renderer)?;
        }
        st.surface.set_positions(new)?;
        b.renderer.set_positions(st.surface.positions())?;
        st.iteration += 1;
        it += 1;
    }
    if params.collision.is_some() {
        st.log.collisions.push(b.collisions);
    }
    Ok(())
}

/// One step of the per-vertex albedo (crate::albedo) from the per-face gradient of a step's rendering, with
/// the block's total-variation weight (nothing when the run fits no albedo).
fn albedo_step(st: &mut RunRecord, params: &ReconstructParams, tv_weight: f64, grad_faces: &[f32]) -> Result<()> {
    let Some(ap) = &params.albedo else { return Ok(()) };
    let settings = albedo::StepSettings {
        adam: &params.reflectance_adam,
        params: ap,
        tv_weight,
        lr: ap.lr * st.lr_scale,
        recentre: params.data.solve_scale,
    };
    albedo::step(&mut st.surface, &mut st.albedo_steps, grad_faces, &settings)
}

/// Step 3: the reflectance block — Adam steps on θ (and on the per-vertex albedo) with the shape fixed,
/// rolled back on a non-finite loss or gradient.
pub(super) fn reflectance_block(
    st: &mut RunRecord,
    ctx: &RunCtx<'_>,
    b: &mut Block<'_>,
    hooks: &mut Hooks<'_>,
) -> Result<()> {
    let params = ctx.params;
    let w_edge = params.boundary_smoothing;
    set_albedo_weights(st, &mut b.renderer)?;
    let (mut r, _) = b.reg.evaluate(st.surface.positions(), st.surface.triangles())?;
    if w_edge > 0.0 {
        r += w_edge * b.edge_reg.evaluate(st.surface.positions())?.0;
    }
    let mut good_refl: Option<GoodReflectance> = None;
    let mut it = 0;
    while it < ctx.refl_iters {
        let ev = evaluate(st, &b.renderer, &b.fit, false);
        let ev = match ev {
            Ok(ev)
                if ev.data.is_finite()
                    && ev.grad_theta.iter().all(|g| g.is_finite())
                    && ev.grad_faces.iter().all(|g| g.is_finite()) =>
            {
                ev
            }
            Ok(_) | Err(OptimError::Brdf(_)) => {
                rollback_refl(st, &mut good_refl, &mut b.renderer, params, "reflectance loss or gradient")?;
                continue;
            }
            Err(e) => return Err(e),
        };
        let loss = ev.data + st.reg_weight * r;
        b.last = loss;
        st.scale = ev.scale;
        let lr = params.lr_reflectance * st.lr_scale;
        st.log.iterations.push(IterationRecord {
            iteration: st.iteration,
            stage: st.stage,
            block: st.block_in_stage,
            kind: StepKind::Reflectance,
            loss,
            data: ev.data,
            regulariser: r,
            reg_weight: st.reg_weight,
            scale: ev.scale,
            step_size: lr,
            faces: st.surface.n_faces(),
            vertices: st.surface.n_vertices(),
            time_s: ctx.elapsed(),
            noise_floor: None,
        });
        let _ = report(hooks, &progress(st, ProgressEvent::Iteration, ctx.planned, loss, b.target, ctx.elapsed()));
        good_refl = Some((st.reflectance.clone(), st.reflectance_adam.clone(), st.surface.clone(), st.albedo_steps));
        if ctx.fit_brdf {
            let delta = st.reflectance_adam.step(&params.reflectance_adam, &ev.grad_theta, lr);
            st.reflectance.add_theta(&delta);
        }
        albedo_step(st, params, b.tv_weight, &ev.grad_faces)?;
        set_albedo_weights(st, &mut b.renderer)?;
        st.iteration += 1;
        it += 1;
    }
    Ok(())
}

/// Step 4: boundary pruning ([`crate::prune`]), the region tests ([`crate::regions`]) and, at the end of a
/// stage but the last, the residual patches ([`crate::residual`], in rounds). Returns the stage's mesh as fitted when patches joined it.
pub(super) fn prune_and_patch(
    st: &mut RunRecord,
    ctx: &RunCtx<'_>,
    b: &Block<'_>,
    end: &BlockEnd,
) -> Result<Option<SurfaceMesh>> {
    let params = ctx.params;
    let residual =
        params.residual.as_ref().filter(|r| end.stage_ends && !end.last_block && r.stages.is_none_or(|n| st.stage < n));
    let mut stage_mesh: Option<SurfaceMesh> = None;
    let last_stage = params.schedule.max_stages.saturating_sub(1);
    let regions = params
        .regions
        .as_ref()
        .filter(|r| b.renderer.face_weights().is_some() && st.stage >= r.first_stage.min(last_stage));
    if params.prune.is_none() && regions.is_none() && residual.is_none() {
        return Ok(stage_mesh);
    }
    let (data, sensor, norm) = (b.fit.measured, b.fit.sensor, b.fit.norm);
    let brdf = st.reflectance.brdf()?;
    let mut rendered = b.renderer.forward_any(&brdf);
    let (bins, scale) = (b.measured.bins(), st.scale);
    // The sensor fit's `J I`, kept current through the deletions (SensorRows::response).
    let response = match sensor {
        Some(m) => Some(RwLock::new(m.response(&rendered)?)),
        None => None,
    };
    let rows = row_terms(&b.fit, bins, scale, response.as_ref());
    let row_loss: &RowLoss<'_> = &*rows;
    let mut keep = vec![true; st.surface.n_faces()];
    if let Some(pp) = &params.prune {
        let p = prune_boundary(st.surface.triangles(), &b.renderer, &brdf, &mut rendered, bins, row_loss, pp)?;
        keep = p.keep;
        st.prune_log.push(PruneRecord {
            stage: st.stage,
            block: st.block_in_stage,
            tested: p.tested,
            removed: p.removed,
            data_change: p.data_change / norm,
        });
    }
    if let (Some(rp), Some(weights)) = (regions, b.renderer.face_weights()) {
        let noise = match (sensor, ctx.counts) {
            (Some(_), _) => RegionNoise::Poisson,
            (None, true) => RegionNoise::Counts { scale },
            (None, false) => RegionNoise::None,
        };
        let (triangles, renderer) = (st.surface.triangles(), &b.renderer);
        let fit = RegionFit { renderer, brdf: &brdf, rendered: &mut rendered, bins, row_loss };
        let rim = st.stage >= rp.rim_stage.min(last_stage);
        let r = dark_regions(triangles, weights, &keep, fit, noise, rp, rim)?;
        keep = r.keep;
        let record = RegionRecord {
            stage: st.stage,
            block: st.block_in_stage,
            tested: r.tested,
            deleted: r.deleted,
            removed: r.removed,
            kept: r.tested - r.deleted,
            data_change: r.data_change / norm,
        };
        st.region_log.push(record);
    }
    if keep.iter().any(|k| !k) {
        drop_faces(st, &keep)?;
    }
    if let Some(rp) = residual {
        // The data minus the model of the data term, for the rendering as the rounds leave it.
        let mut residual_of = |rendered: &[f32]| -> Result<Vec<f32>> {
            let model: Vec<f64> = match (sensor, &response) {
                (Some(m), Some(lock)) => {
                    let mut a = lock.write().map_err(|_| crate::data_term::counts::poisoned())?;
                    // The sensor's `J I` of the rendering with the last round's patches.
                    *a = m.response(rendered)?;
                    a.iter().map(|a| scale * a + m.background).collect()
                }
                (Some(m), None) => m.expected(rendered, scale)?,
                (None, _) => rendered.iter().map(|&r| scale * f64::from(r)).collect(),
            };
            Ok(data.iter().zip(&model).map(|(&m, &e)| (f64::from(m) - e) as f32).collect())
        };
        let fit = PatchFit { render: *b.renderer.params(), brdf: &brdf, rendered: &mut rendered, row_loss };
        let (positions, triangles) = (st.surface.positions(), st.surface.triangles());
        let rounds = residual_rounds(positions, triangles, b.measured, &mut residual_of, fit, rp)?;
        for (round, p) in rounds.into_iter().enumerate() {
            if !p.triangles.is_empty() && stage_mesh.is_none() {
                stage_mesh = Some(st.surface.mesh()?);
            }
            let remap = Remap::append(&st.surface, &p.positions, &p.triangles);
            st.surface.apply(remap)?;
            let record = ResidualRecord {
                stage: st.stage,
                round,
                columns: p.columns,
                regions: p.regions,
                accepted: p.accepted,
                faces: p.triangles.len(),
                data_change: p.data_change / norm,
                patches: p.notes.into_iter().map(|n| PatchNote { data_change: n.data_change / norm, ..n }).collect(),
            };
            st.log.residual.push(record.clone());
            st.residual_log.push(record);
        }
    }
    Ok(stage_mesh)
}

/// Step 5b: the bookkeeping — self-intersections removed, the stage advanced (its mesh saved as
/// `stage_NN.obj`) or the next block counted, and the checkpoint and run log written.
pub(super) fn bookkeeping(
    st: &mut RunRecord,
    ctx: &RunCtx<'_>,
    b: &Block<'_>,
    end: &BlockEnd,
    stage_mesh: Option<SurfaceMesh>,
) -> Result<()> {
    let params = ctx.params;
    untangle(st, IntersectionCheck::BlockEnd)?;
    st.blocks_done += 1;
    if end.stage_ends {
        if let Some(dir) = &params.out_dir {
            let m = match stage_mesh {
                Some(m) => m,
                None => st.surface.mesh()?,
            };
            nlos_mesh::io::save(&m, dir.join(format!("stage_{:02}.obj", st.stage)))?;
        }
        st.stage += 1;
        st.block_in_stage = 0;
        if let Next::Stop(reason) = ctx.plan.next_stage(st, end, b.target) {
            st.finished = Some(reason);
        }
    } else {
        st.block_in_stage += 1;
    }
    st.elapsed_s = ctx.elapsed();
    if let Some(dir) = &params.out_dir {
        st.write(dir)?;
    }
    Ok(())
}
