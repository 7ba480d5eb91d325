//! Text in the HTML pages `cta` writes (the analysis report, the noise plots).

/// `s` with `&`, `<` and `>` escaped, to go into an HTML page as text.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
