//! One record through the opening scan: every feature `features.json` declares checked against
//! what the `tf.train.Example` stores (its keys, list kinds, value counts and steps), and what
//! the manifest needs of the episode (its length, task, the step markers' problems, each ragged
//! feature's row length).

use std::collections::BTreeMap;

use super::example::{self, Example, Values};
use super::features::{Feature, Kind};
use crate::error::{Error, Result};
use crate::source::mapping::KeyInfo;

/// What the opening scan learns about one episode.
#[derive(Debug, Clone, Default)]
pub(super) struct Scanned {
    pub(super) len: usize,
    pub(super) task: Option<String>,
    /// Problems with the step markers, for the warnings.
    pub(super) markers: Vec<&'static str>,
    /// Whether the language instruction changes within the episode.
    pub(super) task_varies: bool,
    /// Per ragged feature: the constant row length, if every step has the same.
    pub(super) row_lengths: BTreeMap<String, Option<i64>>,
}

impl Scanned {
    /// Every ragged feature the channels read (`read`) has rows as long as the first episode's
    /// (which gave `keys` their widths); `place` names the record.
    pub(super) fn check_ragged(
        &self,
        read: &BTreeMap<String, Feature>,
        keys: &[KeyInfo],
        place: &str,
    ) -> Result<()> {
        for (key, f) in read.iter().filter(|(_, f)| f.kind == Kind::Ragged) {
            let width = keys.iter().find(|k| &k.key == key).map(KeyInfo::width);
            match self.row_lengths.get(key).copied().flatten() {
                Some(n) if Some(n as usize * f.row_width()) == width => {}
                _ => {
                    return Err(Error::source(format!(
                        "{place}: `{key}` is ragged with rows of another length than the first episode's; a channel needs the same width every step"
                    )))
                }
            }
        }
        Ok(())
    }
}

fn disagrees(place: &str, message: String) -> Error {
    Error::source(format!(
        "{place}: the record disagrees with features.json: {message}"
    ))
}

/// Checks one record against the feature spec and learns what the manifest needs.
pub(super) fn scan_record(data: &[u8], declared: &[Feature], place: &str) -> Result<Scanned> {
    let ex = example::parse(data)
        .map_err(|e| Error::source(format!("{place}: not a tf.train.Example: {e}")))?;
    let mut out = Scanned::default();
    let mut steps: Option<(usize, &str)> = None;
    let mut stored = 0;
    for f in declared {
        stored += check_stored(&ex, f, place)?;
        let Some(this) = steps_of(&ex, f, place, &mut out.row_lengths)? else {
            continue;
        };
        match steps {
            None => steps = Some((this, f.key.as_str())),
            Some((s, other)) if s != this => {
                return Err(disagrees(
                    place,
                    format!("`{}` has {this} steps, but `{other}` has {s}", f.key),
                ))
            }
            _ => {}
        }
        if f.kind == Kind::Text && f.key.ends_with("language_instruction") {
            if let Values::Bytes(v) = &ex[&f.key] {
                let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
                out.task = v.first().map(|b| text(b));
                out.task_varies = v.iter().any(|b| Some(text(b)) != out.task);
            }
        }
    }
    if stored != ex.len() {
        let wanted: Vec<String> = declared.iter().flat_map(Feature::stored_keys).collect();
        let extra: Vec<String> = ex
            .keys()
            .filter(|k| !wanted.contains(k))
            .map(|k| format!("`{k}`"))
            .collect();
        let extra = extra.join(", ");
        return Err(disagrees(
            place,
            format!("it stores {extra}, which features.json does not declare"),
        ));
    }
    out.len = steps.map_or(0, |s| s.0);
    out.markers = markers(&ex, out.len);
    Ok(out)
}

/// Every key feature `f` is stored under is in the record, in the list TFDS stores it in; how
/// many keys that is.
fn check_stored(ex: &Example, f: &Feature, place: &str) -> Result<usize> {
    let keys = f.stored_keys();
    for key in &keys {
        let Some(values) = ex.get(key) else {
            return Err(disagrees(
                place,
                format!("`{key}` is declared but not stored"),
            ));
        };
        let list = if key.ends_with("/ragged_row_lengths_0") {
            "int64_list"
        } else {
            f.list()
        };
        // An empty list carries no kind: TFDS writes empty episodes' lists that way.
        if !values.is_empty() && values.kind() != list {
            let what = match &f.kind {
                Kind::Image { .. } => "image",
                Kind::Text => "text",
                _ => "tensor",
            };
            return Err(disagrees(
                place,
                format!(
                    "`{key}` is a {} {what}, which TFDS stores as a {list}, but the record has a {}",
                    f.dtype,
                    values.kind()
                ),
            ));
        }
    }
    Ok(keys.len())
}

/// How many steps feature `f` holds in the record; `None` when it says nothing of them (a
/// per-episode feature, checked here; a tensor with no values per step; a kind chunkc does not
/// read). A ragged feature's row length, when constant, goes into `row_lengths`.
fn steps_of(
    ex: &Example,
    f: &Feature,
    place: &str,
    row_lengths: &mut BTreeMap<String, Option<i64>>,
) -> Result<Option<usize>> {
    let n = ex[&f.stored_keys()[0]].len();
    if !f.per_step {
        let want = match f.kind {
            Kind::Tensor => f.width(),
            Kind::Text | Kind::Image { .. } => 1,
            _ => return Ok(None),
        };
        if n != want {
            return Err(disagrees(
                place,
                format!(
                    "`{}` holds {n} values, but its shape {:?} needs {want}",
                    f.key, f.shape
                ),
            ));
        }
        return Ok(None);
    }
    let steps = match f.kind {
        Kind::Tensor => {
            let w = f.width().max(if f.shape.is_empty() { 1 } else { 0 });
            if w == 0 {
                return Ok(None);
            }
            if !n.is_multiple_of(w) {
                return Err(disagrees(
                    place,
                    format!(
                        "`{}` holds {n} values, not a multiple of its per-step shape {:?}",
                        f.key, f.shape
                    ),
                ));
            }
            n / w
        }
        Kind::Image { .. } | Kind::Text => n,
        Kind::Ragged => ragged_rows(ex, f, place, row_lengths)?,
        Kind::Other(_) => return Ok(None),
    };
    Ok(Some(steps))
}

/// A ragged feature's rows (steps): its row lengths add up to its flat values; the length of
/// every row, when they are all alike, goes into `row_lengths`.
fn ragged_rows(
    ex: &Example,
    f: &Feature,
    place: &str,
    row_lengths: &mut BTreeMap<String, Option<i64>>,
) -> Result<usize> {
    let rows = match &ex[&format!("{}/ragged_row_lengths_0", f.key)] {
        Values::Int64(v) => v.clone(),
        _ => Vec::new(),
    };
    let total: i64 = rows.iter().sum();
    let flat = ex[&format!("{}/ragged_flat_values", f.key)].len();
    if rows.iter().any(|&r| r < 0) || total as usize * f.row_width() != flat {
        return Err(disagrees(
            place,
            format!(
                "`{}`: the row lengths add up to {total} rows, but {flat} values are stored",
                f.key
            ),
        ));
    }
    let constant = rows
        .first()
        .copied()
        .filter(|r| rows.iter().all(|x| x == r));
    row_lengths.insert(f.key.clone(), constant);
    Ok(rows.len())
}

/// What is wrong with the RLDS step markers: first step first, last step last, terminal only
/// at the end.
fn markers(ex: &Example, len: usize) -> Vec<&'static str> {
    let flags = |name: &str| match ex.get(&format!("steps/{name}")) {
        Some(Values::Int64(v)) if v.len() == len => Some(v.clone()),
        _ => None,
    };
    let mut out = Vec::new();
    if let Some(v) = flags("is_first") {
        if v.first() != Some(&1) || v.iter().skip(1).any(|&x| x != 0) {
            out.push("`steps/is_first` is not set on exactly the first step");
        }
    }
    if let Some(v) = flags("is_last") {
        if v.last() != Some(&1) || v.iter().rev().skip(1).any(|&x| x != 0) {
            out.push("`steps/is_last` is not set on exactly the last step");
        }
    }
    if let Some(v) = flags("is_terminal") {
        if v.iter().rev().skip(1).any(|&x| x != 0) {
            out.push("`steps/is_terminal` is set before the last step");
        }
    }
    out
}
