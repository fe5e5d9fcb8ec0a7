//! RLDS as TFDS's `RLDSDatasetBuilder` writes it (the Open X-Embodiment layout):
//!
//! ```text
//! rlds/1.0.0/dataset_info.json     splits, shardLengths, filepathTemplate
//! rlds/1.0.0/features.json         steps/{action, observation/{state, cam<c>}, reward, discount,
//!                                  is_first, is_last, is_terminal, language_instruction},
//!                                  episode_metadata/episode_id
//! rlds/1.0.0/synth_rlds-train.tfrecord-XXXXX-of-YYYYY   one tf.train.Example per episode
//! ```
//! Frames are JPEG (quality 95, 4:2:0, as TFDS's `Image` feature encodes them), one per step.
//! RLDS stores no time, so only a `drop` fault leaves a trace (shorter episodes).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::{SynthEpisode, SynthOptions, SynthWriter};
use crate::error::{Error, IoContext, Result};
use crate::source::rlds::example::{self, Values};
use crate::source::rlds::tfrecord;

/// The dataset's name in file names and `dataset_info.json`.
pub const NAME: &str = "synth_rlds";
/// Episodes per shard (TFDS aims at shards of a few hundred MB; this keeps several shards
/// for the benchmark's sizes, so that they are read in parallel).
const PER_SHARD: usize = 64;

pub struct RldsWriter {
    dir: PathBuf,
    opts: SynthOptions,
    shards: usize,
    written: usize,
    current: Option<BufWriter<File>>,
    lengths: Vec<u64>,
}

impl RldsWriter {
    pub fn create(opts: &SynthOptions, root: &Path) -> Result<Self> {
        let dir = root.join("1.0.0");
        std::fs::create_dir_all(&dir).at("create", &dir)?;
        let shards = opts.episodes.div_ceil(PER_SHARD);
        Ok(RldsWriter {
            dir,
            opts: opts.clone(),
            shards,
            written: 0,
            current: None,
            lengths: Vec::new(),
        })
    }

    fn shard_path(&self, x: usize) -> PathBuf {
        self.dir.join(format!(
            "{NAME}-train.tfrecord-{x:05}-of-{:05}",
            self.shards
        ))
    }
}

fn tensor(shape: &[usize], dtype: &str) -> Value {
    let class = if shape.is_empty() {
        "scalar.Scalar"
    } else {
        "tensor_feature.Tensor"
    };
    json!({
        "pythonClassName": format!("tensorflow_datasets.core.features.{class}"),
        "tensor": {
            "shape": {"dimensions": shape.iter().map(|d| d.to_string()).collect::<Vec<_>>()},
            "dtype": dtype,
            "encoding": "none"
        }
    })
}

fn dict(features: serde_json::Map<String, Value>) -> Value {
    json!({
        "pythonClassName": "tensorflow_datasets.core.features.features_dict.FeaturesDict",
        "featuresDict": {"features": features}
    })
}

/// `features.json` for the options.
pub fn features_json(o: &SynthOptions) -> Value {
    let mut obs = serde_json::Map::new();
    obs.insert("state".into(), tensor(&[o.state_dim], "float32"));
    for c in 0..o.cameras {
        obs.insert(
            format!("cam{c}"),
            json!({
                "pythonClassName": "tensorflow_datasets.core.features.image_feature.Image",
                "image": {
                    "shape": {"dimensions": [o.height.to_string(), o.width.to_string(), "3"]},
                    "dtype": "uint8",
                    "encodingFormat": "jpeg"
                }
            }),
        );
    }
    let mut steps = serde_json::Map::new();
    steps.insert("action".into(), tensor(&[o.action_dim], "float32"));
    steps.insert("observation".into(), dict(obs));
    steps.insert("reward".into(), tensor(&[], "float32"));
    steps.insert("discount".into(), tensor(&[], "float32"));
    for flag in ["is_first", "is_last", "is_terminal"] {
        steps.insert(flag.into(), tensor(&[], "bool"));
    }
    steps.insert(
        "language_instruction".into(),
        json!({"pythonClassName": "tensorflow_datasets.core.features.text_feature.Text", "text": {}}),
    );
    let mut meta = serde_json::Map::new();
    meta.insert("episode_id".into(), tensor(&[], "int32"));
    let mut top = serde_json::Map::new();
    top.insert(
        "steps".into(),
        json!({
            "pythonClassName": "tensorflow_datasets.core.features.dataset_feature.Dataset",
            "sequence": {"feature": dict(steps), "length": "-1"}
        }),
    );
    top.insert("episode_metadata".into(), dict(meta));
    dict(top)
}

/// The task of synthetic episode `id` (a handful of instructions, cycled).
pub fn task(id: u64) -> String {
    const TASKS: [&str; 3] = ["pick up the cube", "open the drawer", "push the block left"];
    TASKS[id as usize % TASKS.len()].to_string()
}

fn encode_example(o: &SynthOptions, ep: &SynthEpisode) -> Result<Vec<u8>> {
    let t = ep.steps;
    let mut jpegs: Vec<Vec<Vec<u8>>> = Vec::new();
    let frame = o.height * o.width * 3;
    for fr in &ep.frames {
        let mut cam = Vec::with_capacity(t);
        for s in 0..t {
            let image = turbojpeg::Image {
                pixels: &fr[s * frame..(s + 1) * frame],
                width: o.width,
                pitch: o.width * 3,
                height: o.height,
                format: turbojpeg::PixelFormat::RGB,
            };
            let jpeg = turbojpeg::compress(image, 95, turbojpeg::Subsamp::Sub2x2)
                .map_err(|e| Error::output(format!("cannot encode a JPEG frame: {e}")))?;
            cam.push(jpeg.to_vec());
        }
        jpegs.push(cam);
    }
    let task = task(ep.id);
    let flag = |at: usize| Values::Int64((0..t).map(|s| i64::from(s == at)).collect());
    let mut features: Vec<(String, Values)> = vec![
        ("steps/action".into(), Values::Float(ep.action.clone())),
        (
            "steps/observation/state".into(),
            Values::Float(ep.state.clone()),
        ),
        (
            "steps/reward".into(),
            Values::Float((0..t).map(|s| f32::from(s + 1 == t)).collect()),
        ),
        ("steps/discount".into(), Values::Float(vec![1.0; t])),
        ("steps/is_first".into(), flag(0)),
        ("steps/is_last".into(), flag(t - 1)),
        ("steps/is_terminal".into(), flag(t - 1)),
        (
            "steps/language_instruction".into(),
            Values::Bytes(vec![task.as_bytes(); t]),
        ),
        (
            "episode_metadata/episode_id".into(),
            Values::Int64(vec![ep.id as i64]),
        ),
    ];
    for (c, cam) in jpegs.iter().enumerate() {
        features.push((
            format!("steps/observation/cam{c}"),
            Values::Bytes(cam.iter().map(Vec::as_slice).collect()),
        ));
    }
    let borrowed: Vec<(&str, Values)> = features
        .iter()
        .map(|(k, v)| (k.as_str(), v.clone()))
        .collect();
    Ok(example::encode(&borrowed))
}

impl SynthWriter for RldsWriter {
    fn episode(&mut self, ep: &SynthEpisode) -> Result<()> {
        let x = self.written / PER_SHARD;
        if self.written.is_multiple_of(PER_SHARD) {
            if let Some(mut w) = self.current.take() {
                w.flush()
                    .map_err(|e| Error::output(format!("cannot write a shard: {e}")))?;
            }
            let path = self.shard_path(x);
            let f = File::create(&path).at("create", &path)?;
            self.current = Some(BufWriter::with_capacity(1 << 20, f));
            self.lengths.push(0);
        }
        let record = encode_example(&self.opts, ep)?;
        let mut framed = Vec::with_capacity(record.len() + 16);
        tfrecord::frame(&record, &mut framed);
        let path = self.shard_path(x);
        self.current
            .as_mut()
            .expect("a shard is open")
            .write_all(&framed)
            .at("write", &path)?;
        self.lengths[x] += 1;
        self.written += 1;
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        if let Some(mut w) = self.current.take() {
            w.flush()
                .map_err(|e| Error::output(format!("cannot write a shard: {e}")))?;
        }
        let info = json!({
            "fileFormat": "tfrecord",
            "moduleName": "chunkc.synth",
            "name": NAME,
            "splits": [{
                "filepathTemplate": "{DATASET}-{SPLIT}.{FILEFORMAT}-{SHARD_X_OF_Y}",
                "name": "train",
                "shardLengths": self.lengths.iter().map(|n| n.to_string()).collect::<Vec<_>>(),
            }],
            "version": "1.0.0"
        });
        for (name, doc) in [
            ("dataset_info.json", info),
            ("features.json", features_json(&self.opts)),
        ] {
            let path = self.dir.join(name);
            let mut text = serde_json::to_string_pretty(&doc).expect("JSON serializes");
            text.push('\n');
            std::fs::write(&path, text).at("write", &path)?;
        }
        Ok(())
    }
}
