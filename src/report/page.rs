//! A small HTML page builder: one self-contained file with inline CSS and inline SVG, no
//! scripts, no external references, so a report opens anywhere and can be attached to an issue.
//! The markup is also well-formed XML (every element closed, attributes quoted).

/// Escapes text for element content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "
body { font-family: sans-serif; margin: 2em auto; max-width: 1000px; color: #222; padding: 0 1em; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
p.sub { color: #666; margin-top: 0; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
th { background: #f2f2f2; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.badge { display: inline-block; padding: 0 0.5em; border-radius: 0.6em; color: #fff; font-size: 0.85em; }
.warn { background: #fff4e0; border-left: 4px solid #e69500; padding: 0.4em 0.8em; margin: 0.4em 0; }
.ok { background: #eaf6ea; border-left: 4px solid #2e8b3e; padding: 0.4em 0.8em; margin: 0.4em 0; }
figure { margin: 1em 0; }
figcaption { color: #555; font-size: 0.9em; }
svg { max-width: 100%; height: auto; }
";

/// A report page, built top to bottom.
pub struct Page {
    title: String,
    body: String,
}

impl Page {
    pub fn new(title: &str, subtitle: &str) -> Self {
        let mut body = format!("<h1>{}</h1>\n", escape(title));
        if !subtitle.is_empty() {
            body += &format!("<p class=\"sub\">{}</p>\n", escape(subtitle));
        }
        Page {
            title: title.to_string(),
            body,
        }
    }

    pub fn heading(&mut self, text: &str) {
        self.body += &format!("<h2>{}</h2>\n", escape(text));
    }

    pub fn paragraph(&mut self, text: &str) {
        self.body += &format!("<p>{}</p>\n", escape(text));
    }

    /// A highlighted note: `warn` (orange) or `ok` (green).
    pub fn note(&mut self, class: &str, text: &str) {
        self.body += &format!("<div class=\"{class}\">{}</div>\n", escape(text));
    }

    /// A table; cells are text, escaped here. Cells that parse as numbers are right-aligned.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.body += "<table>\n<tr>";
        for h in header {
            self.body += &format!("<th>{}</th>", escape(h));
        }
        self.body += "</tr>\n";
        for row in rows {
            self.body += "<tr>";
            for cell in row {
                let class = if cell.parse::<f64>().is_ok() {
                    " class=\"num\""
                } else {
                    ""
                };
                self.body += &format!("<td{class}>{}</td>", escape(cell));
            }
            self.body += "</tr>\n";
        }
        self.body += "</table>\n";
    }

    /// An SVG drawing (from [`super::plot`]) with a caption.
    pub fn figure(&mut self, svg: &str, caption: &str) {
        self.body += &format!(
            "<figure>\n{}\n<figcaption>{}</figcaption>\n</figure>\n",
            strip_xml_declaration(svg),
            escape(caption)
        );
    }

    pub fn finish(self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n\
             <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{}<p class=\"sub\">\
             Written by chunkc {}.</p>\n</body>\n</html>\n",
            escape(&self.title),
            self.body,
            env!("CARGO_PKG_VERSION")
        )
    }
}

/// An `<?xml …?>` line is not allowed inside HTML.
fn strip_xml_declaration(svg: &str) -> &str {
    match svg.trim_start().strip_prefix("<?xml") {
        Some(rest) => rest
            .split_once("?>")
            .map_or(svg, |(_, after)| after.trim_start()),
        None => svg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_everywhere() {
        let mut page = Page::new("a <b> & \"c\"", "");
        page.paragraph("<script>alert(1)</script>");
        page.table(&["x<y"], &[vec!["1 & 2".into()]]);
        let html = page.finish();
        assert!(!html.contains("<script"));
        assert!(!html.contains("<b>"));
        assert!(html.contains("a &lt;b&gt; &amp; &quot;c&quot;"));
        assert!(html.contains("1 &amp; 2"));
    }

    #[test]
    fn xml_declaration_is_dropped_from_inline_svg() {
        assert_eq!(
            strip_xml_declaration("<?xml version=\"1.0\"?>\n<svg/>"),
            "<svg/>"
        );
        assert_eq!(strip_xml_declaration("<svg/>"), "<svg/>");
    }
}
