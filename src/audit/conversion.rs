//! Rate conversion: how a rate is reached from the source's (decimation by an integer factor, or
//! resampling), and its application to an episode's channel. A profile's rate is reached so
//! (`plan`), and so is a mixture's from each of its sources' ([`super::mixture`]).

use serde::Serialize;

use crate::source::ChannelData;
use crate::spec::ResampleMethod;

/// How a profile's rate is reached from the source's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Conversion {
    /// Keep steps 0, `factor`, 2 `factor`, … of each episode (`factor` 1: the source rate).
    Decimate { factor: usize },
    /// A rate that does not divide the source's: each whole episode of n steps resampled to
    /// round(n × `to` / `from`) steps (`[audit] resample`: Fourier or linear; images take the
    /// nearest frame).
    Resample {
        from: f64,
        to: f64,
        method: ResampleMethod,
    },
}

impl Conversion {
    /// Steps of an episode of `len` source steps after conversion.
    pub fn len(&self, len: usize) -> usize {
        match *self {
            Conversion::Decimate { factor } => len.div_ceil(factor),
            Conversion::Resample { from, to, .. } => {
                ((len as f64 * to / from).round() as usize).max(usize::from(len > 0))
            }
        }
    }

    /// The decimation factor, if this is one.
    pub fn factor(&self) -> Option<usize> {
        match *self {
            Conversion::Decimate { factor } => Some(factor),
            Conversion::Resample { .. } => None,
        }
    }
}

/// How to get from `source_fps` to `fps`: integer decimation when the ratio is an integer, else
/// resampling; or a message saying why neither works.
pub fn conversion(
    source_fps: f64,
    fps: f64,
    method: ResampleMethod,
) -> std::result::Result<Conversion, String> {
    if fps > source_fps * (1.0 + 1e-9) {
        return Err(format!(
            "{fps} Hz is faster than the source's {source_fps} Hz; chunkc does not upsample"
        ));
    }
    let ratio = source_fps / fps;
    let factor = ratio.round();
    if (ratio - factor).abs() > 1e-6 * ratio {
        return Ok(Conversion::Resample {
            from: source_fps,
            to: fps,
            method,
        });
    }
    Ok(Conversion::Decimate {
        factor: factor as usize,
    })
}

impl Conversion {
    /// A channel of `width` values per step of an episode of `len` steps, converted (its values
    /// borrowed: the caller keeps them).
    pub fn apply(&self, values: &ChannelData, width: usize, len: usize) -> ChannelData {
        match *self {
            Conversion::Decimate { factor } => match values {
                ChannelData::Lowdim(v) => ChannelData::Lowdim(decimate(v, width, factor)),
                ChannelData::Image(v) => ChannelData::Image(decimate(v, width, factor)),
            },
            Conversion::Resample { method, .. } => {
                super::repair::convert_rate(values, width, self.len(len), method)
            }
        }
    }
}

/// Every `factor`-th row of `width` values, from the first.
fn decimate<T: Copy>(values: &[T], width: usize, factor: usize) -> Vec<T> {
    if factor == 1 || width == 0 {
        return values.to_vec();
    }
    let mut out = Vec::with_capacity((values.len() / width).div_ceil(factor) * width);
    for row in values.chunks_exact(width).step_by(factor) {
        out.extend_from_slice(row);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{conversion, Conversion};
    use crate::spec::ResampleMethod::Fourier;

    #[test]
    fn decimate_or_resample() {
        assert_eq!(
            conversion(50.0, 10.0, Fourier),
            Ok(Conversion::Decimate { factor: 5 })
        );
        assert_eq!(
            conversion(10.0, 10.0, Fourier),
            Ok(Conversion::Decimate { factor: 1 })
        );
        let c = conversion(30.0, 20.0, Fourier).unwrap();
        assert_eq!(c.factor(), None);
        assert_eq!(c.len(31), 21);
        assert_eq!(c.len(30), 20);
        assert!(conversion(10.0, 50.0, Fourier).is_err());
    }
}
