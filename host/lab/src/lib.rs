//! The CTA lab library: the domain behind the `cta` tool.

#![warn(missing_docs)]
// Checks are written `!(x > 0.0)` on purpose: a NaN fails them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod analyze;
pub mod boards;
pub mod bounded;
pub mod budget;
pub mod crosstalk;
pub mod data;
pub mod fit;
pub mod html;
pub mod nearfield;
pub mod noise;
pub mod plot;
pub mod pose;
pub mod progress;
pub mod provenance;
pub mod sim;
pub mod sweep;
pub mod uncertainty;
