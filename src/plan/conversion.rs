//! Rate conversion: how a profile's rate is reached from the source's (decimation by an integer
//! factor, or resampling), and the order in which rates are listed.

use serde::Serialize;

use crate::spec::ResampleMethod;
use crate::window::decimated_len;

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
            Conversion::Decimate { factor } => decimated_len(len, factor),
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

/// Orders rates from the fastest: the source rate first, as decimation factors 1, 2, … did.
pub(super) fn rate_order(fps: f64) -> usize {
    usize::MAX - (fps * 1e6).round() as usize
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
