//! `dataset_info.json`: the dataset's name, its splits and, per split, the shard files and how
//! many episodes each holds (`shardLengths`), from TFDS's `filepathTemplate`
//! (`{DATASET}-{SPLIT}.{FILEFORMAT}-{SHARD_X_OF_Y}`, shards numbered `00000-of-00004`).

use serde_json::Value;

/// One shard of a split.
#[derive(Debug, Clone, PartialEq)]
pub struct Shard {
    /// File name inside the version directory.
    pub file: String,
    /// Episodes (records) `dataset_info.json` says it holds.
    pub episodes: u64,
}

/// One TFDS split.
#[derive(Debug, Clone, PartialEq)]
pub struct Split {
    pub name: String,
    pub shards: Vec<Shard>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct DatasetInfo {
    pub name: String,
    pub splits: Vec<Split>,
}

fn number(v: &Value) -> Option<u64> {
    match v {
        Value::String(s) => s.parse().ok(),
        Value::Number(n) => n.as_u64(),
        _ => None,
    }
}

/// Fills a TFDS file path template.
pub fn fill(
    template: &str,
    dataset: &str,
    split: &str,
    format: &str,
    x: usize,
    y: usize,
) -> String {
    template
        .replace("{DATASET}", dataset)
        .replace("{SPLIT}", split)
        .replace("{FILEFORMAT}", format)
        .replace("{SHARD_X_OF_Y}", &format!("{x:05}-of-{y:05}"))
        .replace("{SHARD_INDEX}", &format!("{x:05}"))
        .replace("{NUM_SHARDS}", &format!("{y:05}"))
}

/// Parses `dataset_info.json` (`shown` names it in messages).
pub fn parse(bytes: &[u8], shown: &str) -> Result<DatasetInfo, String> {
    let root: Value =
        serde_json::from_slice(bytes).map_err(|e| format!("{shown}: not valid JSON: {e}"))?;
    let name = root
        .get("name")
        .and_then(Value::as_str)
        .ok_or_else(|| format!("{shown}: no `name`"))?
        .to_string();
    let format = root
        .get("fileFormat")
        .and_then(Value::as_str)
        .unwrap_or("tfrecord");
    if format != "tfrecord" {
        return Err(format!(
            "{shown}: `fileFormat` is `{format}`; chunkc reads TFRecord shards only"
        ));
    }
    let splits = root
        .get("splits")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("{shown}: no `splits` list"))?;
    let mut out = Vec::new();
    for (i, s) in splits.iter().enumerate() {
        let split = s
            .get("name")
            .and_then(Value::as_str)
            .ok_or_else(|| format!("{shown}: `splits[{i}]` has no `name`"))?;
        let template = s
            .get("filepathTemplate")
            .and_then(Value::as_str)
            .unwrap_or("{DATASET}-{SPLIT}.{FILEFORMAT}-{SHARD_X_OF_Y}");
        let lengths = s
            .get("shardLengths")
            .and_then(Value::as_array)
            .ok_or_else(|| format!("{shown}: split `{split}` has no `shardLengths`"))?;
        let n = lengths.len();
        let shards = lengths
            .iter()
            .enumerate()
            .map(|(x, len)| {
                let episodes = number(len).ok_or_else(|| {
                    format!("{shown}: split `{split}`: `shardLengths[{x}]` is {len}, not a count")
                })?;
                let file = fill(template, &name, split, format, x, n);
                if file.contains('/') || file.contains("..") {
                    return Err(format!(
                        "{shown}: split `{split}`: shard path `{file}` leaves the directory"
                    ));
                }
                Ok(Shard { file, episodes })
            })
            .collect::<Result<Vec<_>, String>>()?;
        out.push(Split {
            name: split.to_string(),
            shards,
        });
    }
    if out.is_empty() {
        return Err(format!("{shown}: `splits` is empty"));
    }
    Ok(DatasetInfo { name, splits: out })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_shards_from_the_template() {
        let json = br#"{"name": "bridge_dataset", "fileFormat": "tfrecord", "splits": [
            {"name": "train", "filepathTemplate": "{DATASET}-{SPLIT}.{FILEFORMAT}-{SHARD_X_OF_Y}",
             "shardLengths": ["3", "4"]},
            {"name": "val", "shardLengths": [2]}]}"#;
        let info = parse(json, "dataset_info.json").unwrap();
        assert_eq!(
            info.splits[0].shards[1].file,
            "bridge_dataset-train.tfrecord-00001-of-00002"
        );
        assert_eq!(info.splits[0].shards[1].episodes, 4);
        assert_eq!(
            info.splits[1].shards[0].file,
            "bridge_dataset-val.tfrecord-00000-of-00001"
        );
        let bad = br#"{"name": "x", "splits": [{"name": "train", "shardLengths": ["a"]}]}"#;
        assert!(parse(bad, "d").unwrap_err().contains("shardLengths[0]"));
    }
}
