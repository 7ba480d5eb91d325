//! Small parsers of option values shared by the commands.

/// `N` comma-separated finite numbers (`--head X,Y,Z`, `sensor sim --offset X,Y`); `example`
/// is shown in the error.
pub fn parse_floats<const N: usize>(
    s: &str,
    names: &str,
    example: &str,
) -> std::result::Result<[f64; N], String> {
    let bad = || format!("{s:?}: expected {N} comma-separated numbers {names} (e.g. {example})");
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != N {
        return Err(bad());
    }
    let mut v = [0.0f64; N];
    for (x, p) in v.iter_mut().zip(parts) {
        *x = p.trim().parse().map_err(|_| bad())?;
        if !x.is_finite() {
            return Err(bad());
        }
    }
    Ok(v)
}

/// Parse `x,y` (two numbers, comma-separated: `--offset 0.3,-0.2`).
pub fn parse_xy(s: &str) -> std::result::Result<[f64; 2], String> {
    parse_floats(s, "x,y", "0.3,-0.2")
}
