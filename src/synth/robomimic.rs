//! robomimic's one-file layout (`demos.hdf5`), or with `--robosuite` the older robosuite files
//! it grew out of.
//!
//! ```text
//! /data                        attrs: total (int64), env_args (JSON text)
//! /data/demo_<i>               attrs: num_samples (int64)
//!   actions                    (T, A) float64
//!   states                     (T, 1 + S) float64; column 0 is simulation time in seconds,
//!                              where the timing faults show
//!   rewards, dones             (T,) float64 / uint8
//!   obs/robot0_joint_pos       (T, S) float64
//!   obs/robot0_joint_vel       (T, S) float64
//!   obs/cam<c>_image           (T, H, W, 3) uint8, chunks (1, H, W, 3), gzip 4
//! /mask/train, /mask/valid     demo names (every 10th demo is valid)
//! ```
//! `--robosuite` leaves out `obs`, `num_samples` and the masks: chunkc then reads the episode's
//! timestamps from `states[:, 0]` (with `obs` present, robomimic's layout, it does not).

use std::path::Path;

use hdf5::types::VarLenUnicode;
use hdf5::File;

use super::aloha::{create_file, dataset, group};
use super::{SynthEpisode, SynthOptions, SynthWriter};
use crate::error::{Error, Result};

pub struct RobomimicWriter {
    file: File,
    data: hdf5::Group,
    opts: SynthOptions,
    names: Vec<String>,
    total: i64,
}

fn text(s: &str) -> Result<VarLenUnicode> {
    s.parse::<VarLenUnicode>()
        .map_err(|e| Error::Internal(format!("attribute text {s:?}: {e}")))
}

fn f64s(values: &[f32]) -> Vec<f64> {
    values.iter().map(|&v| v as f64).collect()
}

impl RobomimicWriter {
    pub fn create(opts: &SynthOptions, path: &Path) -> Result<Self> {
        let file = create_file(path)?;
        let data = group(&file, "data")?;
        Ok(RobomimicWriter {
            file,
            data,
            opts: opts.clone(),
            names: Vec::new(),
            total: 0,
        })
    }
}

impl SynthWriter for RobomimicWriter {
    fn episode(&mut self, ep: &SynthEpisode) -> Result<()> {
        let o = &self.opts;
        let name = format!("demo_{}", ep.id);
        let g = group(&self.data, &name)?;
        let t = ep.steps;
        let s = o.state_dim;
        let mut states = vec![0f64; t * (1 + s)];
        for i in 0..t {
            states[i * (1 + s)] = ep.timestamps[i];
            for d in 0..s {
                states[i * (1 + s) + 1 + d] = ep.state[i * s + d] as f64;
            }
        }
        dataset(&g, "actions", &f64s(&ep.action), &[t, o.action_dim])?;
        dataset(&g, "states", &states, &[t, 1 + s])?;
        let mut rewards = vec![0f64; t];
        let mut dones = vec![0u8; t];
        rewards[t - 1] = 1.0;
        dones[t - 1] = 1;
        dataset(&g, "rewards", &rewards, &[t])?;
        dataset(&g, "dones", &dones, &[t])?;
        if !o.robosuite {
            g.new_attr::<i64>()
                .create("num_samples")?
                .write_scalar(&(t as i64))?;
            let obs = group(&g, "obs")?;
            dataset(&obs, "robot0_joint_pos", &f64s(&ep.state), &[t, s])?;
            dataset(&obs, "robot0_joint_vel", &f64s(&ep.velocity), &[t, s])?;
            for (c, fr) in ep.frames.iter().enumerate() {
                let ds = obs
                    .new_dataset::<u8>()
                    .shape([t, o.height, o.width, 3])
                    .chunk([1, o.height, o.width, 3])
                    .deflate(4)
                    .obj_track_times(false)
                    .create(format!("cam{c}_image").as_str())?;
                ds.write_raw(fr.as_slice())?;
            }
        }
        self.names.push(name);
        self.total += t as i64;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<()> {
        self.data
            .new_attr::<i64>()
            .create("total")?
            .write_scalar(&self.total)?;
        let env = r#"{"env_name": "chunkc_synth", "type": 1, "env_kwargs": {}}"#;
        self.data
            .new_attr::<VarLenUnicode>()
            .create("env_args")?
            .write_scalar(&text(env)?)?;
        if !self.opts.robosuite {
            let mask = group(&self.file, "mask")?;
            let mut train: Vec<&String> = Vec::new();
            let mut valid: Vec<&String> = Vec::new();
            for (i, n) in self.names.iter().enumerate() {
                if i % 10 == 9 {
                    valid.push(n);
                } else {
                    train.push(n);
                }
            }
            for (key, names) in [("train", train), ("valid", valid)] {
                let width = names.iter().map(|n| n.len()).max().unwrap_or(6).max(6);
                // Fixed-length byte strings, as robomimic's h5py writes `np.array(names, "S")`.
                let mut bytes = vec![0u8; names.len() * width];
                for (j, n) in names.iter().enumerate() {
                    bytes[j * width..j * width + n.len()].copy_from_slice(n.as_bytes());
                }
                write_fixed_strings(&mask, key, &bytes, names.len(), width)?;
            }
        }
        Ok(())
    }
}

/// A 1-D dataset of fixed-length ASCII strings (`|S<width>` in numpy).
fn write_fixed_strings(
    group: &hdf5::Group,
    name: &str,
    bytes: &[u8],
    count: usize,
    width: usize,
) -> Result<()> {
    use hdf5::types::FixedAscii;
    macro_rules! write_n {
        ($($n:literal)*) => {
            match width {
                $($n => {
                    let values: Vec<FixedAscii<$n>> = bytes
                        .chunks(width)
                        .map(|c| {
                            let end = c.iter().position(|&b| b == 0).unwrap_or(c.len());
                            FixedAscii::<$n>::from_ascii(&c[..end]).expect("ASCII demo name")
                        })
                        .collect();
                    let ds = group
                        .new_dataset::<FixedAscii<$n>>()
                        .shape([count])
                        .obj_track_times(false)
                        .create(name)?;
                    ds.write_raw(&values)?;
                }),*
                _ => return Err(Error::Internal(format!("demo names of {width} characters"))),
            }
        };
    }
    write_n!(6 7 8 9 10 11 12 13 14 15 16);
    Ok(())
}
