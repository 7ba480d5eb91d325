//! The CTA lab library: the domain behind the `cta` tool.

// Checks are written `!(x > 0.0)` on purpose: a NaN fails them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod analyze;
pub mod boards;
pub mod budget;
pub mod data;
pub mod fit;
pub mod html;
pub mod nearfield;
pub mod noise;
pub mod plot;
pub mod progress;
pub mod pose;
pub mod sim;
pub mod sweep;
pub mod uncertainty;

/// What the binary does with a command's error: prints `cta: error: ...` with its causes and
/// exits with 1, or an interrupted sweep's [`sweep::Interrupted::exit_code`] (128 + the
/// signal). Returns on success.
pub fn exit_on_error(r: anyhow::Result<()>) {
    if let Err(e) = r {
        eprintln!("cta: error: {e:#}");
        let code = e
            .downcast_ref::<sweep::Interrupted>()
            .map_or(1, |i| i.exit_code);
        std::process::exit(code);
    }
}
