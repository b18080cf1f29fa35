//! # nlos-optim
//!
//! The analysis-by-synthesis loop of Tsai, Sankaranarayanan & Gkioulekas, "Beyond Volumetric Albedo — A
//! Surface Optimization Framework for Non-Line-of-Sight Imaging", CVPR 2019 (equation numbers are theirs):
//! render the transient of a candidate mesh (`nlos_render`), compare it with the measurement, differentiate,
//! step with Adam, remesh, repeat — coarse to fine.
//!
//! Building blocks:
//! - [`loss`]: the data term — L2 of eq. (7) or Poisson NLL (`nlos_render::Loss`), per-bin weights, and an
//!   unknown global intensity scale solved in closed form at every step;
//! - [`regularizer`]: the normal-smoothing term of Delaunoy & Prados (IJCV 2011) with its exact gradient and
//!   the automatic weight.
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate: it is also true for NaN, which is how non-finite values reach the guards.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod error;
pub mod loss;
pub mod regularizer;

pub use error::{OptimError, Result};
pub use loss::{DataEval, DataTerm};
pub use nlos_render::Loss;
pub use regularizer::{NormalSmoothing, auto_weight};
