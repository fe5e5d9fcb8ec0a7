//! The text `chunkc init` writes: a commented spec.

use std::fmt::Write;
use std::path::{Component, Path, PathBuf};

use super::key_role::{KeyRole, Role};
use super::Inspection;
use crate::spec::SourceFormat;

/// One `[source.channels]` line: our name, the source key, the columns kept.
pub type Mapping = (String, String, Option<[usize; 2]>);

pub fn mapping_of(r: &KeyRole) -> Mapping {
    (
        r.channel.clone().unwrap_or_default(),
        r.key.clone(),
        r.columns,
    )
}

/// A TOML basic string.
fn quote(s: &str) -> String {
    let mut out = String::from('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A TOML key: bare when it can be, quoted otherwise (`"observation.state"`).
fn key(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        s.to_string()
    } else {
        quote(s)
    }
}

pub(super) fn number(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{x:.0}")
    } else {
        format!("{x}")
    }
}

pub(super) fn format_name(f: SourceFormat) -> String {
    serde_json::to_value(f)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default()
}

/// `to` relative to the directory `from` (both absolute), with `/` separators; `to` itself when
/// the two share nothing below the root (`/data/set` from `/tmp`).
pub fn relative(to: &Path, from: &Path) -> String {
    let norm = |p: &Path| -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for c in p.components() {
            match c {
                Component::ParentDir => {
                    out.pop();
                }
                Component::Normal(s) => out.push(s.to_string_lossy().into_owned()),
                _ => {}
            }
        }
        out
    };
    let (a, b) = (norm(to), norm(from));
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return format!("/{}", a.join("/"));
    }
    let mut parts: Vec<String> = vec!["..".into(); b.len() - common];
    parts.extend(a[common..].iter().cloned());
    if parts.is_empty() {
        ".".into()
    } else {
        parts.join("/")
    }
}

fn channel_line(m: &Mapping) -> String {
    match m.2 {
        Some([a, b]) => format!(
            "{} = {{ key = {}, columns = [{a}, {b}] }}",
            quote(&m.0),
            quote(&m.1)
        ),
        None => format!("{} = {}", quote(&m.0), quote(&m.1)),
    }
}

/// The parts of a spec every draft shares.
#[derive(Debug, Clone, Copy)]
pub struct Draft<'a> {
    pub format: SourceFormat,
    /// The dataset, absolute.
    pub path: &'a Path,
    /// `source.fps`, where the source stores no rate.
    pub fps: Option<f64>,
    /// `output.dir`, relative to the spec.
    pub out_dir: &'a str,
    /// Where the spec lives (absolute): paths in it are relative to this.
    pub spec_dir: &'a Path,
    /// `[audit] video = "exclude_episode"`: a camera's missing videos exclude their episodes.
    pub exclude_bad_videos: bool,
}

impl<'a> Draft<'a> {
    pub fn with_fps(self, fps: Option<f64>) -> Self {
        Draft { fps, ..self }
    }

    pub fn excluding_bad_videos(self, exclude_bad_videos: bool) -> Self {
        Draft {
            exclude_bad_videos,
            ..self
        }
    }

    fn source_path(&self) -> String {
        relative(self.path, self.spec_dir)
    }

    /// A spec with these channels, the doctor off and one profile at the source rate: what the
    /// inspection opens, audits and analyzes.
    pub fn render_minimal(&self, channels: &[Mapping]) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "version = 1\n[source]");
        let _ = writeln!(t, "format = {}", quote(&format_name(self.format)));
        let _ = writeln!(t, "path = {}", quote(&self.source_path()));
        if let Some(fps) = self.fps {
            let _ = writeln!(t, "fps = {}", number(fps));
        }
        let _ = writeln!(t, "[source.channels]");
        for m in channels {
            let _ = writeln!(t, "{}", channel_line(m));
        }
        if self.exclude_bad_videos {
            let _ = writeln!(t, "[audit]\nvideo = \"exclude_episode\"");
        }
        let _ = writeln!(t, "[audit.doctor]\nenabled = false");
        let _ = writeln!(t, "[output]\ndir = {}", quote(self.out_dir));
        let _ = writeln!(t, "[profiles.probe]\npreset = \"lerobot_act\"");
        t
    }
}

pub(super) fn shape(s: &[usize]) -> String {
    let dims: Vec<String> = s.iter().map(|d| d.to_string()).collect();
    format!("({})", dims.join(", "))
}

/// The spec `chunkc init` writes, with the reasons as comments.
// Long function: the spec's sections in order, each with its comments.
pub fn spec(ins: &Inspection, spec_dir: &Path, out_dir: &str) -> String {
    let draft = Draft {
        format: ins.format,
        path: &ins.path,
        fps: ins.spec_fps,
        out_dir,
        spec_dir,
        exclude_bad_videos: !ins.missing_videos.is_empty(),
    };
    let mut t = String::new();
    let w = &mut t;
    let _ = writeln!(
        w,
        "# Written by `chunkc init` ({}) from {}.",
        env!("CARGO_PKG_VERSION"),
        draft.source_path()
    );
    let _ = writeln!(
        w,
        "# {} episode(s), {} steps ({}..{} per episode). Read it, then `chunkc check` and `chunkc build`.",
        ins.episodes, ins.steps, ins.shortest, ins.longest
    );
    let _ = writeln!(w, "# Every key is explained in the book's spec reference.");
    let _ = writeln!(w, "version = 1\n\n[source]");
    let _ = writeln!(
        w,
        "format = {}  # {}",
        quote(&format_name(ins.format)),
        ins.evidence
    );
    let _ = writeln!(w, "path = {}", quote(&draft.source_path()));
    match draft.fps {
        Some(fps) => {
            let _ = writeln!(w, "fps = {}  # {}", number(fps), ins.rate.origin);
            if ins.rate.guessed {
                let _ = writeln!(
                    w,
                    "# ^ a GUESS: set the rate the robot was recorded at (or run `chunkc init --fps HZ`)"
                );
            }
        }
        None => {
            let _ = writeln!(
                w,
                "# the rate, {} Hz, comes from {}",
                number(ins.rate.fps),
                ins.rate.origin
            );
        }
    }

    let _ = writeln!(w, "\n[source.channels]");
    let width = ins
        .mapped()
        .map(|r| channel_line(&mapping_of(r)).len())
        .max()
        .unwrap_or(0);
    for r in ins.mapped() {
        let line = channel_line(&mapping_of(r));
        let mut about = format!("{} {} {}", r.role.word(), shape(&r.shape), r.dtype);
        if let Some(n) = &r.note {
            about.push_str(": ");
            about.push_str(n);
        }
        let _ = writeln!(w, "{line:width$}  # {about}");
    }
    let left: Vec<&KeyRole> = ins
        .keys
        .iter()
        .filter(|r| r.channel.is_none() && !matches!(r.role, Role::Bookkeeping))
        .collect();
    if !left.is_empty() {
        let _ = writeln!(w, "# Not mapped:");
        for r in left {
            let name = r.suggested.clone().unwrap_or_default();
            let why = r.note.clone().unwrap_or_else(|| r.role.word().to_string());
            let _ = writeln!(
                w,
                "# {} = {}  # {} {}: {why}",
                quote(&name),
                quote(&r.key),
                shape(&r.shape),
                r.dtype
            );
        }
    }
    let bookkeeping: Vec<&str> = ins
        .keys
        .iter()
        .filter(|r| r.role == Role::Bookkeeping)
        .map(|r| r.key.as_str())
        .collect();
    if !bookkeeping.is_empty() {
        let _ = writeln!(
            w,
            "# Bookkeeping, never a channel: {}",
            bookkeeping.join(", ")
        );
    }
    if ins.tasks > 0 {
        let _ = writeln!(
            w,
            "# Language: {} distinct task(s), carried into meta.json and the LeRobot export's tasks.",
            ins.tasks
        );
    }

    let _ = writeln!(w, "\n[split]");
    match &ins.split_origin {
        Some(origin) => {
            let _ = writeln!(
                w,
                "from = \"source\"  # the split the source stores ({origin})"
            );
        }
        None if ins.episodes < 2 => {
            let _ = writeln!(w, "val_fraction = 0.0  # one episode: nothing to hold out");
        }
        None => {
            let _ = writeln!(w, "val_fraction = 0.1  # by episode, seeded\nseed = 0");
        }
    }

    let _ = writeln!(w, "\n[audit]");
    if draft.exclude_bad_videos {
        let missing: Vec<String> = ins
            .missing_videos
            .iter()
            .map(|m| format!("`{}` in {} episode(s)", m.channel, m.episodes.len()))
            .collect();
        let _ = writeln!(
            w,
            "video = \"exclude_episode\"  # episodes without their camera videos are left out: {} (listed under [source.channels])",
            missing.join(", ")
        );
    }
    let timing = &ins.timing;
    if timing.timestamps {
        let _ = writeln!(
            w,
            "# Timing audit at {} Hz: {} episode(s) ok, {} to interpolate, {} to resample, {} to exclude.",
            number(ins.rate.fps),
            timing.ok,
            timing.interpolate,
            timing.resample,
            timing.exclude
        );
    } else {
        let _ = writeln!(
            w,
            "# The source stores no timestamps: the audit takes every step as 1/{} s.",
            number(ins.rate.fps)
        );
    }
    if timing.video_problems > 0 {
        let _ = writeln!(
            w,
            "# {} camera video(s) disagree with their rows: see `chunkc audit`.",
            timing.video_problems
        );
    }
    for warning in &timing.warnings {
        let _ = writeln!(w, "# audit: {warning}");
    }
    let _ = writeln!(
        w,
        "# The dataset doctor (signal checks) is on by default: [audit.doctor]."
    );

    let _ = writeln!(w, "\n[output]\ndir = {}", quote(out_dir));
    for p in &ins.profiles {
        let _ = writeln!(w);
        for line in &p.why {
            let _ = writeln!(w, "# {line}");
        }
        let _ = writeln!(w, "[profiles.{}]", key(&p.name));
        let _ = writeln!(w, "preset = {}", quote(&p.preset));
        if let Some(fps) = p.fps {
            let _ = writeln!(w, "fps = {}", number(fps));
        }
        let _ = writeln!(w, "chunk = {}", p.chunk);
        if let Some(e) = p.executes {
            let _ = writeln!(w, "executes = {e}");
        }
        if let Some(f) = &p.format {
            let _ = writeln!(w, "format = {}", quote(f));
        }
    }
    t
}

/// Where a spec written to `out` lives (absolute), for relative paths inside it.
pub fn spec_dir(out: &Path) -> PathBuf {
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::path::absolute(parent).unwrap_or_else(|_| parent.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths() {
        assert_eq!(
            relative(Path::new("/a/b/data"), Path::new("/a/c")),
            "../b/data"
        );
        assert_eq!(relative(Path::new("/a/b"), Path::new("/a/b")), ".");
        assert_eq!(relative(Path::new("/a/b/c"), Path::new("/a")), "b/c");
        assert_eq!(relative(Path::new("/a/./b/../c"), Path::new("/a")), "c");
        assert_eq!(
            relative(Path::new("/data/set"), Path::new("/tmp")),
            "/data/set"
        );
    }

    #[test]
    fn toml_keys_and_strings() {
        assert_eq!(key("act"), "act");
        assert_eq!(key("observation.state"), "\"observation.state\"");
        assert_eq!(quote("a\"b\\c"), "\"a\\\"b\\\\c\"");
    }
}
