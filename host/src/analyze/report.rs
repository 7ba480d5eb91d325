//! The self-contained HTML report of `cta analyze --report DIR`.
use super::Analysis;
use std::path::Path;

/// Write `DIR/index.html`.
pub fn write(dir: &Path, a: &Analysis) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(
        dir.join("index.html"),
        format!("<pre>{}</pre>", super::render_text(a)),
    )?;
    Ok(())
}
