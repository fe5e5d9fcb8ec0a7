//! `features.json`, the nested TFDS feature spec, flattened to the keys the Examples hold.
//!
//! TFDS serializes a `FeaturesDict` by joining the nested names with `/`; the `steps` feature
//! (a `Dataset`) stores each step feature's values concatenated over the episode, so a
//! per-step feature of shape `s` holds `steps × product(s)` values. Storage types follow TFDS:
//! floats (float64 too) in a `float_list`, integers and bools in an `int64_list`, text and
//! encoded images in a `bytes_list` (one encoded image per step). A tensor with an unknown
//! dimension is ragged: `<key>/ragged_flat_values` and `<key>/ragged_row_lengths_0`.

use serde_json::Value;

/// What a flattened feature holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Kind {
    /// Numbers (`Tensor`, `Scalar`, `ClassLabel`), per-step shape known.
    Tensor,
    /// Numbers with an unknown leading dimension, stored ragged.
    Ragged,
    /// One encoded image per step (`encodingFormat`: jpeg or png).
    Image { format: String },
    /// UTF-8 strings.
    Text,
    /// Anything else TFDS knows (audio, video, bounding boxes…): listed, not readable.
    Other(String),
}

/// One flattened feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    /// `steps/observation/image_0`, `episode_metadata/file_path`.
    pub key: String,
    /// Under `steps`: one value set per step. Otherwise one per episode.
    pub per_step: bool,
    pub kind: Kind,
    /// The TFDS dtype (`float32`, `bool`, `uint8`, `string`).
    pub dtype: String,
    /// Per-step (or per-episode) shape; `None` for an unknown dimension.
    pub shape: Vec<Option<usize>>,
}

/// The storage list TFDS uses for a dtype.
pub fn list_for(dtype: &str) -> &'static str {
    match dtype {
        "float16" | "float32" | "float64" | "bfloat16" => "float_list",
        "string" => "bytes_list",
        _ => "int64_list",
    }
}

/// Flattens `features.json` (`shown` names it in messages).
pub fn parse(bytes: &[u8], shown: &str) -> Result<Vec<Feature>, String> {
    let root: Value =
        serde_json::from_slice(bytes).map_err(|e| format!("{shown}: not valid JSON: {e}"))?;
    let mut out = Vec::new();
    walk(&root, "", false, &mut out).map_err(|e| format!("{shown}: {e}"))?;
    if out.is_empty() {
        return Err(format!("{shown}: declares no features"));
    }
    Ok(out)
}

fn class(node: &Value) -> &str {
    node.get("pythonClassName")
        .and_then(Value::as_str)
        .and_then(|c| c.rsplit('.').next())
        .unwrap_or("")
}

fn shape(node: Option<&Value>, key: &str) -> Result<Vec<Option<usize>>, String> {
    let Some(dims) = node
        .and_then(|s| s.get("dimensions"))
        .and_then(Value::as_array)
    else {
        return Ok(Vec::new());
    };
    dims.iter()
        .map(|d| {
            let n = match d {
                Value::String(s) => s.parse::<i64>().ok(),
                Value::Number(n) => n.as_i64(),
                _ => None,
            }
            .ok_or_else(|| format!("`{key}`: dimension {d} is not a number"))?;
            Ok((n >= 0).then_some(n as usize))
        })
        .collect()
}

// Long function: one arm per TFDS feature type of features.json (FeaturesDict, Sequence, Tensor, Image, Text, Scalar).
fn walk(node: &Value, path: &str, per_step: bool, out: &mut Vec<Feature>) -> Result<(), String> {
    let join = |name: &str| {
        if path.is_empty() {
            name.to_string()
        } else {
            format!("{path}/{name}")
        }
    };
    let key = path.to_string();
    match class(node) {
        "FeaturesDict" => {
            let features = node
                .pointer("/featuresDict/features")
                .and_then(Value::as_object)
                .ok_or_else(|| {
                    format!("`{key}`: a FeaturesDict without `featuresDict.features`")
                })?;
            for (name, child) in features {
                walk(child, &join(name), per_step, out)?;
            }
        }
        "Dataset" | "Sequence" => {
            if per_step {
                return Err(format!(
                    "`{key}`: a sequence inside a sequence is not supported"
                ));
            }
            let inner = node
                .pointer("/sequence/feature")
                .ok_or_else(|| format!("`{key}`: a {} without `sequence.feature`", class(node)))?;
            walk(inner, path, true, out)?;
        }
        "Tensor" | "Scalar" | "ClassLabel" => {
            let tensor = node.get("tensor");
            let dtype = tensor
                .and_then(|t| t.get("dtype"))
                .and_then(Value::as_str)
                .unwrap_or(if class(node) == "ClassLabel" {
                    "int64"
                } else {
                    ""
                })
                .to_string();
            let encoding = tensor
                .and_then(|t| t.get("encoding"))
                .and_then(Value::as_str)
                .unwrap_or("none");
            let shape = shape(tensor.and_then(|t| t.get("shape")), &key)?;
            let kind = if encoding != "none" {
                Kind::Other(format!("tensor with encoding `{encoding}`"))
            } else if dtype == "string" {
                Kind::Text
            } else if shape.iter().any(Option::is_none) {
                Kind::Ragged
            } else {
                Kind::Tensor
            };
            out.push(Feature {
                key,
                per_step,
                kind,
                dtype,
                shape,
            });
        }
        "Image" => {
            let image = node.get("image");
            let format = image
                .and_then(|i| i.get("encodingFormat"))
                .and_then(Value::as_str)
                .unwrap_or("png")
                .to_string();
            let dtype = image
                .and_then(|i| i.get("dtype"))
                .and_then(Value::as_str)
                .unwrap_or("uint8")
                .to_string();
            out.push(Feature {
                shape: shape(image.and_then(|i| i.get("shape")), &key)?,
                key,
                per_step,
                kind: Kind::Image { format },
                dtype,
            });
        }
        "Text" => out.push(Feature {
            key,
            per_step,
            kind: Kind::Text,
            dtype: "string".into(),
            shape: Vec::new(),
        }),
        other => out.push(Feature {
            key,
            per_step,
            kind: Kind::Other(if other.is_empty() {
                "a feature without `pythonClassName`".into()
            } else {
                other.to_string()
            }),
            dtype: String::new(),
            shape: Vec::new(),
        }),
    }
    Ok(())
}

impl Feature {
    /// Values per step (or per episode) of a fixed-shape tensor.
    pub fn width(&self) -> usize {
        self.shape.iter().map(|d| d.unwrap_or(0)).product()
    }

    /// Values per row of a ragged feature (the product of its known dimensions after the rows).
    pub fn row_width(&self) -> usize {
        self.shape.iter().skip(1).map(|d| d.unwrap_or(1)).product()
    }

    /// The Example keys this feature is stored under.
    pub fn stored_keys(&self) -> Vec<String> {
        match self.kind {
            Kind::Ragged => vec![
                format!("{}/ragged_flat_values", self.key),
                format!("{}/ragged_row_lengths_0", self.key),
            ],
            _ => vec![self.key.clone()],
        }
    }

    /// The storage list of the feature's values.
    pub fn list(&self) -> &'static str {
        match self.kind {
            Kind::Image { .. } | Kind::Text => "bytes_list",
            _ => list_for(&self.dtype),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flattens_nested_dicts() {
        let json = br#"{"pythonClassName": "tensorflow_datasets.core.features.features_dict.FeaturesDict",
          "featuresDict": {"features": {
            "steps": {"pythonClassName": "tensorflow_datasets.core.features.dataset_feature.Dataset",
              "sequence": {"feature": {"pythonClassName": "tensorflow_datasets.core.features.features_dict.FeaturesDict",
                "featuresDict": {"features": {
                  "action": {"pythonClassName": "tensorflow_datasets.core.features.features_dict.FeaturesDict",
                    "featuresDict": {"features": {
                      "world_vector": {"pythonClassName": "tensorflow_datasets.core.features.tensor_feature.Tensor",
                        "tensor": {"shape": {"dimensions": ["3"]}, "dtype": "float32", "encoding": "none"}}}}},
                  "points": {"pythonClassName": "tensorflow_datasets.core.features.tensor_feature.Tensor",
                    "tensor": {"shape": {"dimensions": ["-1", "2"]}, "dtype": "float64", "encoding": "none"}},
                  "image": {"pythonClassName": "tensorflow_datasets.core.features.image_feature.Image",
                    "image": {"shape": {"dimensions": ["8", "8", "3"]}, "dtype": "uint8", "encodingFormat": "jpeg"}}}}}},
              "length": "-1"},
            "episode_metadata": {"pythonClassName": "tensorflow_datasets.core.features.features_dict.FeaturesDict",
              "featuresDict": {"features": {"file_path": {"pythonClassName": "tensorflow_datasets.core.features.text_feature.Text", "text": {}}}}}}}}"#;
        let f = parse(json, "features.json").unwrap();
        let keys: Vec<&str> = f.iter().map(|f| f.key.as_str()).collect();
        assert_eq!(
            keys,
            [
                "steps/action/world_vector",
                "steps/points",
                "steps/image",
                "episode_metadata/file_path"
            ]
        );
        assert!(f[0].per_step && !f[3].per_step);
        assert_eq!(f[0].width(), 3);
        assert_eq!(f[1].kind, Kind::Ragged);
        assert_eq!(f[1].list(), "float_list");
        assert_eq!(
            f[1].stored_keys(),
            [
                "steps/points/ragged_flat_values",
                "steps/points/ragged_row_lengths_0"
            ]
        );
        assert_eq!(
            f[2].kind,
            Kind::Image {
                format: "jpeg".into()
            }
        );
        assert_eq!(f[3].kind, Kind::Text);
    }
}
