//! One self-contained HTML page: pictures as data URIs and charts as inline SVG, so the file alone shows
//! everything, offline. A script counts the pictures that decoded and writes the count on `<body>`
//! (`data-images-loaded` of `data-images`), for a headless browser to check.

use base64::Engine as _;
use std::fmt::Write as _;

/// An HTML page under construction.
pub struct Page {
    title: String,
    body: String,
    images: usize,
}

/// `text` with HTML's special characters escaped.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{margin-top:1.8em;border-bottom:1px solid #ddd}h3{margin-top:1.2em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
figure{display:inline-block;margin:.4em .6em .8em 0;vertical-align:top}figcaption{font-size:.85em;color:#555}
img{max-width:100%;image-rendering:auto}.pix{image-rendering:pixelated}
.charts svg{max-width:100%;height:auto}code{background:#f5f5f5;padding:0 .2em}.note{color:#666;font-size:.9em}";

const CHECK: &str = "<script>
window.addEventListener('load', function () {
  var imgs = document.querySelectorAll('img');
  var ok = 0;
  imgs.forEach(function (i) { if (i.complete && i.naturalWidth > 0) ok++; });
  document.body.setAttribute('data-images', imgs.length);
  document.body.setAttribute('data-images-loaded', ok);
  document.body.setAttribute('data-charts', document.querySelectorAll('svg').length);
});
</script>";

impl Page {
    pub fn new(title: &str) -> Self {
        Self {
            title: title.to_string(),
            body: String::new(),
            images: 0,
        }
    }

    /// A heading, level 1–4.
    pub fn heading(&mut self, level: u8, text: &str) {
        let l = level.clamp(1, 4);
        let _ = writeln!(self.body, "<h{l}>{}</h{l}>", escape(text));
    }

    /// A paragraph of plain text.
    pub fn text(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
    }

    /// A paragraph in a quieter style.
    pub fn note(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p class=\"note\">{}</p>", escape(text));
    }

    /// HTML written by the caller (it escapes what it takes from files).
    pub fn raw(&mut self, html: &str) {
        self.body.push_str(html);
        self.body.push('\n');
    }

    /// A PNG (still or animated) with a caption, shown `zoom` times its size (above 1, with sharp pixels:
    /// small renders stay readable).
    pub fn png(&mut self, png: &[u8], caption: &str, zoom: u32) {
        let data = base64::engine::general_purpose::STANDARD.encode(png);
        // The width is in the header (IHDR, bytes 16–19).
        let width = png.get(16..20).map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
        let size = match (zoom > 1, width) {
            (true, Some(w)) => format!(" class=\"pix\" width=\"{}\"", w * zoom),
            _ => String::new(),
        };
        let _ = writeln!(
            self.body,
            "<figure><img src=\"data:image/png;base64,{data}\" alt=\"{c}\"{size}><figcaption>{c}</figcaption></figure>",
            c = escape(caption),
        );
        self.images += 1;
    }

    /// Charts side by side (SVG documents, inlined).
    pub fn charts(&mut self, svgs: &[String]) {
        self.body.push_str("<div class=\"charts\">\n");
        for s in svgs {
            // An inline <svg> needs no XML prolog.
            let start = s.find("<svg").unwrap_or(0);
            let _ = writeln!(self.body, "<figure>{}</figure>", &s[start..]);
        }
        self.body.push_str("</div>\n");
    }

    /// A table of text cells (escaped).
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.body.push_str("<table><tr>");
        for h in header {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                let _ = write!(self.body, "<td>{}</td>", escape(c));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// How many pictures the page holds.
    pub fn image_count(&self) -> usize {
        self.images
    }

    /// The whole document.
    pub fn finish(self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
             <style>{STYLE}</style></head>\n<body>\n{}{CHECK}\n</body></html>\n",
            escape(&self.title),
            self.body
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_page_embeds_its_pictures_and_escapes_text() {
        let mut p = Page::new("a <b> & c");
        p.heading(2, "fits & <errors>");
        p.text("x < y");
        let png = pganeus_io::encode_png(&pganeus_io::Image::new(3, 2, 3));
        p.png(&png, "first", 2);
        p.table(&["video", "mm"], &[vec!["slide".into(), "2.3".into()]]);
        p.charts(&["<?xml version=\"1.0\"?><svg width=\"1\"></svg>".into()]);
        assert_eq!(p.image_count(), 1);
        let html = p.finish();
        assert!(html.contains("<title>a &lt;b&gt; &amp; c</title>"));
        assert!(html.contains("<h2>fits &amp; &lt;errors&gt;</h2>"));
        assert!(html.contains("src=\"data:image/png;base64,iVBORw0KGgo"));
        assert!(html.contains("alt=\"first\" class=\"pix\" width=\"6\">"), "{html}");
        assert!(html.contains("<figure><svg width=\"1\"></svg></figure>"), "{html}");
        assert!(!html.contains("http://") && !html.contains("https://"));
    }
}
