//! Text in the HTML pages `cta` writes (the analysis report, the noise plots).

/// `s` with `&`, `<` and `>` escaped, to go into an HTML page as text.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// A page of figures, each an image with its caption, and links: what a folder of plots
/// shows, readable on a phone. `figures` are `(file, caption)`, `links` `(href, text)`, both
/// relative to the page.
pub fn gallery(
    title: &str,
    intro: &str,
    figures: &[(&str, &str)],
    links: &[(&str, &str)],
) -> String {
    let mut s = format!(
        "<!doctype html><html><head><meta charset=utf-8>\
         <meta name=viewport content=\"width=device-width, initial-scale=1\">\
         <title>{t}</title><style>body{{font-family:sans-serif;max-width:1100px;margin:auto;\
         padding:1em}}figure{{margin:1.5em 0}}img{{max-width:100%;height:auto;border:1px solid \
         #ddd}}figcaption{{margin-top:0.3em}}</style></head><body><h1>{t}</h1><p>{i}</p>",
        t = escape(title),
        i = escape(intro)
    );
    for (file, caption) in figures {
        s.push_str(&format!(
            "<figure><a href=\"{f}\"><img src=\"{f}\" alt=\"{c}\"></a><figcaption>{c}</figcaption></figure>",
            f = escape(file),
            c = escape(caption)
        ));
    }
    if !links.is_empty() {
        s.push_str("<ul>");
        for (href, text) in links {
            s.push_str(&format!(
                "<li><a href=\"{}\">{}</a></li>",
                escape(href),
                escape(text)
            ));
        }
        s.push_str("</ul>");
    }
    s.push_str("</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gallery_shows_each_figure_with_its_caption() {
        let page = gallery(
            "t <1>",
            "intro",
            &[("a.svg", "A & B"), ("b.svg", "C")],
            &[("r/index.html", "report")],
        );
        assert!(page.contains("<img src=\"a.svg\" alt=\"A &amp; B\">"));
        assert!(page.contains("<figcaption>C</figcaption>"));
        assert!(page.contains("<a href=\"r/index.html\">report</a>"));
        assert!(page.contains("<title>t &lt;1&gt;</title>") && page.contains("name=viewport"));
    }
}
