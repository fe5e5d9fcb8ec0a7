//! One spec error, drawn rustc-style against the spec's text:
//!
//! ```text
//! error: unknown key `chunck` in `[profiles.act]`
//!   --> specs/bad.toml:14:1
//!    |
//! 14 | chunck = 20
//!    | ^^^^^^ unknown key
//!    |
//!    = help: did you mean `chunk`?
//! ```
//!
//! Plain text, no colors: the output is compared by snapshot tests and read in CI logs.

use std::fmt::Write;
use std::ops::Range;

/// A message, the byte range of the text it is about, a short label under that text, and an
/// optional hint.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    pub message: String,
    /// Byte range into the spec's text. `None` only when the error has no place in the file.
    pub span: Option<Range<usize>>,
    pub label: String,
    pub help: Option<String>,
}

impl Diagnostic {
    pub fn new(message: impl Into<String>) -> Self {
        Diagnostic {
            message: message.into(),
            span: None,
            label: String::new(),
            help: None,
        }
    }

    pub fn at(mut self, span: Range<usize>, label: impl Into<String>) -> Self {
        self.span = Some(span);
        self.label = label.into();
        self
    }

    pub fn with_help(mut self, help: Option<String>) -> Self {
        self.help = help;
        self
    }

    /// The diagnostic as text, without a trailing newline. `file` is the name shown after `-->`.
    pub fn render(&self, file: &str, text: &str) -> String {
        let mut out = format!("error: {}\n", self.message);
        let Some(span) = &self.span else {
            let _ = write!(out, " --> {file}");
            if let Some(help) = &self.help {
                let _ = write!(out, "\n  = help: {help}");
            }
            return out;
        };
        let at = Position::of(text, span.start);
        let line_text = &text[at.line_start..at.line_end];
        let width = at.line.to_string().len();
        let pad = " ".repeat(width);
        // A span that runs over several lines is underlined to the end of its first line; an
        // empty one (e.g. "expected `]`" at the end of a line) still gets one caret.
        let mut end = span.end.clamp(at.offset, at.line_end);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        let lead = display_width(&text[at.line_start..at.offset]);
        let carets = display_width(&text[at.offset..end]).max(1);
        let _ = writeln!(out, "{pad}--> {file}:{}:{}", at.line, at.column);
        let _ = writeln!(out, "{pad} |");
        let _ = writeln!(out, "{} | {}", at.line, line_text.replace('\t', TAB));
        let _ = write!(out, "{pad} | {}{}", " ".repeat(lead), "^".repeat(carets));
        if !self.label.is_empty() {
            let _ = write!(out, " {}", self.label);
        }
        if let Some(help) = &self.help {
            let _ = write!(out, "\n{pad} |\n{pad} = help: {help}");
        }
        out
    }
}

/// Tabs are drawn as four spaces so that the carets line up whatever the terminal's tab stops.
const TAB: &str = "    ";

fn display_width(s: &str) -> usize {
    s.chars()
        .map(|c| if c == '\t' { TAB.len() } else { 1 })
        .sum()
}

/// Where a byte offset falls: 1-based line and column (columns count characters, as rustc's do).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Position {
    pub line: usize,
    pub column: usize,
    /// The offset, moved back onto a character boundary and into the text.
    pub offset: usize,
    pub line_start: usize,
    /// End of the line's text, before `\n` or `\r\n`.
    pub line_end: usize,
}

impl Position {
    pub fn of(text: &str, offset: usize) -> Position {
        let mut offset = offset.min(text.len());
        while !text.is_char_boundary(offset) {
            offset -= 1;
        }
        // An offset just past a final newline belongs to the last line, not to an empty one
        // that an editor would not show.
        if offset == text.len() && offset > 0 && text.ends_with('\n') {
            offset -= 1;
        }
        let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
        let line_end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
        let line_end = if text[line_start..line_end].ends_with('\r') {
            line_end - 1
        } else {
            line_end
        };
        // An offset on the `\r` of a `\r\n` (or past a final lone `\r`) is shown at the end of
        // the line's text.
        let offset = offset.min(line_end);
        Position {
            line: text[..line_start].matches('\n').count() + 1,
            column: text[line_start..offset].chars().count() + 1,
            offset,
            line_start,
            line_end,
        }
    }
}

/// The candidate closest to `given`, if any is close enough to be what the user meant.
pub(crate) fn suggest<'a>(given: &str, candidates: &[&'a str]) -> Option<&'a str> {
    let given_lower = given.to_lowercase();
    candidates
        .iter()
        .map(|&c| {
            (
                strsim::damerau_levenshtein(&given_lower, &c.to_lowercase()),
                c,
            )
        })
        // One edit per three characters, as cargo allows, and at least one: short names like
        // `fps` still get a suggestion for a transposition.
        .filter(|&(distance, c)| distance <= (c.chars().count() / 3).max(1))
        .min_by_key(|&(distance, _)| distance)
        .map(|(_, c)| c)
}

/// "did you mean `x`?" when a candidate is close, else the full list of valid names.
pub(crate) fn did_you_mean(given: &str, candidates: &[&str], what: &str) -> Option<String> {
    if let Some(best) = suggest(given, candidates) {
        return Some(format!("did you mean `{best}`?"));
    }
    match candidates {
        [] => None,
        [only] => Some(format!("the only valid {what} is `{only}`")),
        _ => Some(format!("valid {what}s: {}", backticked(candidates))),
    }
}

/// "`a`, `b`, `c`"
pub(crate) fn backticked(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_past_a_carriage_return() {
        // Found by the `spec` fuzz target: a file that is a single `\r` (the error is at
        // offset 1, after the `\r`) made the caret range run backwards.
        let p = Position::of("\r", 1);
        assert_eq!((p.line, p.column, p.offset, p.line_end), (1, 1, 0, 0));
        let p = Position::of("a = 1\r\nb", 6);
        assert_eq!((p.line, p.column, p.offset), (1, 6, 5));
        let out = Diagnostic::new("m").at(1..1, "here").render("f.toml", "\r");
        assert!(out.ends_with("1 | \n  | ^ here"), "{out:?}");
    }

    #[test]
    fn positions_are_one_based() {
        let text = "a = 1\nbb = 2\r\nccc = 3\n";
        let p = Position::of(text, 0);
        assert_eq!((p.line, p.column), (1, 1));
        let p = Position::of(text, text.find("2").unwrap());
        assert_eq!((p.line, p.column), (2, 6));
        assert_eq!(&text[p.line_start..p.line_end], "bb = 2");
        let p = Position::of(text, text.find("ccc").unwrap() + 2);
        assert_eq!((p.line, p.column), (3, 3));
    }

    #[test]
    fn end_of_text_is_on_the_last_line() {
        let p = Position::of("a = \n", 5);
        assert_eq!((p.line, p.column), (1, 5));
        let p = Position::of("a = [1,", 99);
        assert_eq!((p.line, p.column), (1, 8));
    }

    #[test]
    fn columns_count_characters() {
        let text = "name = \"é\" # x\n";
        let p = Position::of(text, text.find('#').unwrap());
        assert_eq!(p.column, 12);
    }

    #[test]
    fn renders_rustc_style() {
        let text = "[profiles.act]\nchunck = 20\n";
        let d = Diagnostic::new("unknown key `chunck` in `[profiles.act]`")
            .at(15..21, "unknown key")
            .with_help(Some("did you mean `chunk`?".into()));
        let expected = "\
error: unknown key `chunck` in `[profiles.act]`
 --> bad.toml:2:1
  |
2 | chunck = 20
  | ^^^^^^ unknown key
  |
  = help: did you mean `chunk`?";
        assert_eq!(d.render("bad.toml", text), expected);
    }

    #[test]
    fn empty_span_gets_one_caret_and_tabs_line_up() {
        let text = "\ta = [1,\n";
        let d = Diagnostic::new("unclosed array").at(8..8, "");
        let out = d.render("x.toml", text);
        assert!(out.ends_with("1 |     a = [1,\n  |            ^"), "{out}");
    }

    #[test]
    fn suggestions() {
        let keys = [
            "preset",
            "fps",
            "chunk",
            "obs_history",
            "stride",
            "normalize",
        ];
        assert_eq!(suggest("chunck", &keys), Some("chunk"));
        assert_eq!(suggest("fsp", &keys), Some("fps"));
        assert_eq!(suggest("CHUNK", &keys), Some("chunk"));
        assert_eq!(suggest("obs_histroy", &keys), Some("obs_history"));
        assert_eq!(suggest("zzz", &keys), None);
        assert_eq!(suggest("actt", &["act", "diffusion_policy"]), Some("act"));
        assert_eq!(
            did_you_mean("lerobt", &["a", "b"], "value").as_deref(),
            Some("valid values: `a`, `b`")
        );
    }
}
