//! The subset of Markdown our `metrics.md` uses (headings, bullet lists, pipe tables,
//! paragraphs, `code`), as HTML: the report shows the very tables `metrics.md` has, so the
//! two never disagree.

/// `text` with `&`, `<`, `>` and `"` escaped.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            _ => out.push(c),
        }
    }
    out
}

/// Escaped inline text with `` `code` `` spans.
fn inline(text: &str) -> String {
    let mut out = String::new();
    for (i, part) in text.split('`').enumerate() {
        if i % 2 == 1 {
            out.push_str(&format!("<code>{}</code>", escape(part)));
        } else {
            out.push_str(&escape(part));
        }
    }
    out
}

fn cells(line: &str) -> Vec<&str> {
    let t = line.trim().trim_start_matches('|').trim_end_matches('|');
    t.split('|').map(str::trim).collect()
}

fn is_rule(line: &str) -> bool {
    cells(line)
        .iter()
        .all(|c| !c.is_empty() && c.chars().all(|ch| ch == '-' || ch == ':'))
}

/// Converts `md`; headings are shifted down by `shift` levels (the page has its own `h1`).
pub fn to_html(md: &str, shift: usize) -> String {
    let mut out = String::new();
    let mut lines = md.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_end();
        if t.is_empty() {
            continue;
        }
        if let Some(level) = t
            .find(' ')
            .filter(|&n| n > 0 && t[..n].chars().all(|c| c == '#'))
        {
            let h = (level + shift).min(6);
            out.push_str(&format!("<h{h}>{}</h{h}>\n", inline(&t[level + 1..])));
        } else if t.starts_with("- ") {
            out.push_str("<ul>\n");
            let mut item = Some(t);
            while let Some(l) = item {
                out.push_str(&format!("<li>{}</li>\n", inline(&l[2..])));
                item = lines.next_if(|l| l.starts_with("- "));
            }
            out.push_str("</ul>\n");
        } else if t.starts_with('|') {
            out.push_str("<table>\n<thead><tr>");
            for c in cells(t) {
                out.push_str(&format!("<th>{}</th>", inline(c)));
            }
            out.push_str("</tr></thead>\n<tbody>\n");
            while let Some(row) = lines.next_if(|l| l.trim_start().starts_with('|')) {
                if is_rule(row) {
                    continue;
                }
                out.push_str("<tr>");
                for c in cells(row) {
                    out.push_str(&format!("<td>{}</td>", inline(c)));
                }
                out.push_str("</tr>\n");
            }
            out.push_str("</tbody></table>\n");
        } else {
            let mut para = vec![t.to_owned()];
            while let Some(l) =
                lines.next_if(|l| !l.trim().is_empty() && !l.starts_with(['#', '|', '-']))
            {
                para.push(l.trim().to_owned());
            }
            out.push_str(&format!("<p>{}</p>\n", inline(&para.join(" "))));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the report's tables: a pipe table becomes one header row and body rows (the
    /// `---` rule dropped), text is escaped (a clip id with `<` cannot inject markup), code
    /// spans and headings (shifted) survive, a list stays one list.
    #[test]
    fn metrics_markdown_becomes_html() {
        let md = "# Title\n\n- a `x<y`\n- b\n\n| m | PSNR (dB) |\n|---|---|\n| model | 10.62 |\n| a&b | n/a |\n\nSome text\ncontinued.\n";
        let html = to_html(md, 1);
        assert_eq!(
            html,
            "<h2>Title</h2>\n<ul>\n<li>a <code>x&lt;y</code></li>\n<li>b</li>\n</ul>\n\
             <table>\n<thead><tr><th>m</th><th>PSNR (dB)</th></tr></thead>\n<tbody>\n\
             <tr><td>model</td><td>10.62</td></tr>\n<tr><td>a&amp;b</td><td>n/a</td></tr>\n\
             </tbody></table>\n<p>Some text continued.</p>\n"
        );
    }
}
