//! Freshness: whether a profile's outputs on disk are what chunkc would build now from the spec
//! and the source, and if not, the first cause that says why.
//!
//! As cargo's `DirtyReason`, each cause is a value of its own ([`DirtyReason`]), shown as text by
//! `chunkc plan` and `build --locked` ([`fmt::Display`]) and as a tagged enum in
//! `plan --format json`. The lock records what is needed to tell the causes apart: per profile the
//! values its fingerprint covers ([`inputs`]), per spec the hash of every source file. A lock
//! written before those records existed still reads; a change it cannot place is then reported
//! as [`DirtyReason::SourceChanged`] or [`DirtyReason::FingerprintChanged`].

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use serde::Serialize;

use super::TOOL_VERSION;
use crate::error::Result;
use crate::lock::{self, SpecLock};
use crate::source::fingerprint::SourcePrint;
use crate::source::Manifest;
use crate::spec::{LoadedSpec, Profile};

/// Whether a profile must be built.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum Status {
    UpToDate,
    Stale { reason: DirtyReason },
}

impl Status {
    pub fn is_up_to_date(&self) -> bool {
        matches!(self, Status::UpToDate)
    }

    /// Why the profile must be built; `None` when it is up to date.
    pub fn reason(&self) -> Option<&DirtyReason> {
        match self {
            Status::UpToDate => None,
            Status::Stale { reason } => Some(reason),
        }
    }
}

/// The first cause, in the order checked, that makes a profile's outputs out of date.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "cause", rename_all = "snake_case")]
pub enum DirtyReason {
    /// The lock has no entry for this spec (or there is no lock).
    NeverBuilt,
    /// The spec's entry in the lock does not know this profile.
    NewProfile { profile: String },
    /// The lock was written by another chunkc version.
    ToolVersionChanged { old: String, new: String },
    /// A spec value the profile depends on differs from the last build (`None`: unset).
    SpecValueChanged {
        key: String,
        old: Option<String>,
        new: Option<String>,
    },
    /// A file the source adapter reads was modified, added or removed (by path in the source).
    SourceFileChanged { file: String, change: FileChange },
    /// The source's fingerprint differs, and the lock does not record which file changed.
    SourceChanged,
    /// The profile's fingerprint differs and the lock cannot tell why (it predates the records).
    FingerprintChanged,
    /// An output file the lock lists is gone.
    OutputMissing { path: String },
    /// An output file's hash differs from the lock's.
    OutputModified { path: String },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FileChange {
    Modified,
    Added,
    Removed,
}

impl fmt::Display for DirtyReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let or_unset = |v: &Option<String>| v.clone().unwrap_or_else(|| "unset".into());
        match self {
            DirtyReason::NeverBuilt => write!(f, "not in chunkc.lock: first build"),
            DirtyReason::NewProfile { profile } => {
                write!(f, "profile `{profile}` is not in chunkc.lock")
            }
            DirtyReason::ToolVersionChanged { old, new } => {
                write!(f, "chunkc changed ({old} -> {new})")
            }
            DirtyReason::SpecValueChanged { key, old, new } => write!(
                f,
                "spec value `{key}` changed ({} -> {})",
                or_unset(old),
                or_unset(new)
            ),
            DirtyReason::SourceFileChanged { file, change } => {
                let how = match change {
                    FileChange::Modified => "was modified",
                    FileChange::Added => "was added",
                    FileChange::Removed => "was removed",
                };
                write!(f, "source file `{file}` {how}")
            }
            DirtyReason::SourceChanged => write!(f, "the source changed"),
            DirtyReason::FingerprintChanged => write!(f, "the spec or the source changed"),
            DirtyReason::OutputMissing { path } => write!(f, "{path} is missing"),
            DirtyReason::OutputModified { path } => write!(f, "{path} was modified"),
        }
    }
}

/// Everything a profile's outputs depend on: the tool, the resolved profile, the source bytes,
/// the channel mapping, the split and the spec's output location. Other profiles' settings are
/// deliberately left out, so editing one profile rebuilds only that one.
///
/// The source's fingerprint may still be pending at plan time (it is completed from the pass's
/// reads), so the value is computed when asked for ([`ProfilePrint::get`]): a first build never
/// needs it before the lock is written.
#[derive(Clone)]
pub struct ProfilePrint {
    /// The spec's values, in the order hashed; the source's fingerprint comes after the first
    /// [`SPEC_PARTS`].
    spec: Vec<String>,
    source: SourcePrint,
}

/// How many of [`ProfilePrint`]'s spec values come before the source's fingerprint.
const SPEC_PARTS: usize = 6;

pub(super) fn profile_fingerprint(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
) -> ProfilePrint {
    let mut parts = vec![
        TOOL_VERSION.to_string(),
        serde_json::to_string(profile).unwrap(),
        serde_json::to_string(&spec.spec.source).unwrap(),
        serde_json::to_string(&spec.spec.split).unwrap(),
        serde_json::to_string(&spec.spec.audit).unwrap(),
        spec.spec.output.dir.clone(),
    ];
    // A mixture's sources and `[mixture]` (nothing for one source: its fingerprint is as before).
    if spec.is_mixture() {
        parts.push(serde_json::to_string(&spec.spec.sources).unwrap());
        parts.push(serde_json::to_string(&spec.spec.mixture).unwrap());
    }
    ProfilePrint {
        spec: parts,
        source: manifest.fingerprint.clone(),
    }
}

impl ProfilePrint {
    /// The fingerprint (BLAKE3, hex), completing the source's if it is still pending.
    pub fn get(&self) -> Result<String> {
        let source = self.source.hash()?;
        let (before, after) = self.spec.split_at(SPEC_PARTS);
        let mut h = blake3::Hasher::new();
        for p in before.iter().chain([&source]).chain(after) {
            h.update(&(p.len() as u64).to_le_bytes());
            h.update(p.as_bytes());
        }
        Ok(h.finalize().to_hex().to_string())
    }
}

impl fmt::Debug for ProfilePrint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ProfilePrint({:?})", self.source)
    }
}

/// Serialized as its value (the source's fingerprint completed if it is still pending).
impl Serialize for ProfilePrint {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let hash = self.get().map_err(serde::ser::Error::custom)?;
        s.serialize_str(&hash)
    }
}

/// The spec values [`profile_fingerprint`] covers, one per leaf, by dotted key
/// (`profiles.act.chunk`, `source.channels.action`, `output.dir`) as JSON text; unset values
/// are absent. The lock keeps them so that a changed fingerprint can name the value.
pub(super) fn inputs(spec: &LoadedSpec, profile: &Profile) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let tables = [
        (format!("profiles.{}", profile.name), json(profile)),
        ("source".into(), json(&spec.spec.source)),
        ("sources".into(), json(&spec.spec.sources)),
        ("mixture".into(), json(&spec.spec.mixture)),
        ("split".into(), json(&spec.spec.split)),
        ("audit".into(), json(&spec.spec.audit)),
        (
            "output.dir".into(),
            serde_json::Value::String(spec.spec.output.dir.clone()),
        ),
    ];
    for (key, value) in tables {
        flatten(key, &value, &mut out);
    }
    out
}

fn json<T: Serialize>(value: &T) -> serde_json::Value {
    serde_json::to_value(value).expect("spec values serialize")
}

fn flatten(key: String, value: &serde_json::Value, out: &mut BTreeMap<String, String>) {
    match value {
        serde_json::Value::Null => {}
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                flatten(format!("{key}.{k}"), v, out);
            }
        }
        other => {
            out.insert(key, other.to_string());
        }
    }
}

/// The first value that differs between the last build's inputs and today's: a value the user
/// wrote before one that only records where a value came from (`….origins.…`).
fn changed_value(
    old: &BTreeMap<String, String>,
    new: &BTreeMap<String, String>,
) -> Option<DirtyReason> {
    let differs = |k: &&String| old.get(*k) != new.get(*k);
    let keys: Vec<&String> = old.keys().chain(new.keys()).filter(differs).collect();
    let key = keys
        .iter()
        .filter(|k| !k.contains(".origins."))
        .min()
        .or_else(|| keys.iter().min())?;
    Some(DirtyReason::SpecValueChanged {
        key: (*key).clone(),
        old: old.get(*key).cloned(),
        new: new.get(*key).cloned(),
    })
}

/// The first source file whose hash differs between the lock and the source as opened now.
fn changed_source_file(
    old: &BTreeMap<String, String>,
    new: &BTreeMap<String, String>,
) -> Option<DirtyReason> {
    let file = old
        .keys()
        .chain(new.keys())
        .filter(|k| old.get(*k) != new.get(*k))
        .min()?;
    let change = match (old.contains_key(file), new.contains_key(file)) {
        (true, true) => FileChange::Modified,
        (false, _) => FileChange::Added,
        (true, false) => FileChange::Removed,
    };
    Some(DirtyReason::SourceFileChanged {
        file: file.clone(),
        change,
    })
}

/// What a profile's freshness is judged from.
pub(super) struct Current<'a> {
    pub name: &'a str,
    pub fingerprint: &'a ProfilePrint,
    pub inputs: &'a BTreeMap<String, String>,
    pub manifest: &'a Manifest,
    /// The profile's output directory.
    pub dir: &'a Path,
}

/// Compares a profile with the last build's lock entry; the causes are checked in the order of
/// [`DirtyReason`]'s variants, the first that holds is the one given.
pub(super) fn status_of(now: &Current, lock: Option<&SpecLock>) -> Result<Status> {
    let stale = |reason| Ok(Status::Stale { reason });
    let Some(lock) = lock else {
        return stale(DirtyReason::NeverBuilt);
    };
    let Some(entry) = lock.profiles.get(now.name) else {
        return stale(DirtyReason::NewProfile {
            profile: now.name.to_string(),
        });
    };
    if lock.tool_version != TOOL_VERSION {
        return stale(DirtyReason::ToolVersionChanged {
            old: lock.tool_version.clone(),
            new: TOOL_VERSION.to_string(),
        });
    }
    let recorded = !entry.inputs.is_empty();
    let value = recorded.then(|| changed_value(&entry.inputs, now.inputs));
    // A changed spec value is the first cause, and needs no source fingerprint: a source that
    // is still pending is then completed from the build's own reads, not read once more now.
    if let Some(Some(reason)) = value {
        return stale(reason);
    }
    if entry.fingerprint != now.fingerprint.get()? {
        let source = now.manifest.fingerprint.get()?;
        let source_changed = lock.source_fingerprint != source.hash;
        let file = (source_changed && !lock.source_files.is_empty())
            .then(|| changed_source_file(&lock.source_files, &source.files));
        let reason = match file.flatten() {
            Some(f) => f,
            None if source_changed => DirtyReason::SourceChanged,
            None => DirtyReason::FingerprintChanged,
        };
        return stale(reason);
    }
    for (file, hash) in &entry.files {
        let path = now.dir.join(file);
        let path_text = path.display().to_string();
        if !path.exists() {
            return stale(DirtyReason::OutputMissing { path: path_text });
        }
        if &lock::hash_file(&path)? != hash {
            return stale(DirtyReason::OutputModified { path: path_text });
        }
    }
    Ok(Status::UpToDate)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn the_value_the_user_wrote_comes_before_its_origin() {
        let old = map(&[
            ("profiles.a.chunk", "20"),
            ("profiles.a.origins.chunk", "\"x\""),
        ]);
        let new = map(&[
            ("profiles.a.chunk", "10"),
            ("profiles.a.origins.chunk", "\"y\""),
        ]);
        assert_eq!(
            changed_value(&old, &new).unwrap().to_string(),
            "spec value `profiles.a.chunk` changed (20 -> 10)"
        );
        let new = map(&[("profiles.a.origins.chunk", "\"x\"")]);
        assert_eq!(
            changed_value(&old, &new).unwrap().to_string(),
            "spec value `profiles.a.chunk` changed (20 -> unset)"
        );
        assert_eq!(changed_value(&old, &old), None);
    }

    #[test]
    fn source_files_added_removed_modified() {
        let old = map(&[("a", "1"), ("b", "2")]);
        let cases = [
            (
                map(&[("a", "1"), ("b", "3")]),
                "source file `b` was modified",
            ),
            (map(&[("a", "1")]), "source file `b` was removed"),
            (
                map(&[("a", "1"), ("b", "2"), ("c", "4")]),
                "source file `c` was added",
            ),
        ];
        for (new, want) in cases {
            assert_eq!(changed_source_file(&old, &new).unwrap().to_string(), want);
        }
    }

    #[test]
    fn json_is_tagged_by_cause() {
        let s = Status::Stale {
            reason: DirtyReason::SpecValueChanged {
                key: "profiles.a.chunk".into(),
                old: Some("20".into()),
                new: None,
            },
        };
        assert_eq!(
            serde_json::to_string(&s).unwrap(),
            r#"{"state":"stale","reason":{"cause":"spec_value_changed","key":"profiles.a.chunk","old":"20","new":null}}"#
        );
        assert_eq!(
            serde_json::to_string(&Status::UpToDate).unwrap(),
            r#"{"state":"up_to_date"}"#
        );
    }
}
