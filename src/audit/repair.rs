//! Applies a verdict to an episode as read: new regular timestamps, numeric channels by cubic
//! spline (re-grid) or resampling, image channels by the nearest frame. Values are computed in
//! `f64` from the source's `f32` and stored back as `f32`.

use super::timing::{drop_repeats, Repair};
use super::{resample, spline};
use crate::source::{ChannelData, ChannelInfo, Episode};

/// Index of the time in `times` (increasing) nearest to `t`; ties go to the earlier one.
fn nearest_time(times: &[f64], t: f64) -> usize {
    let after = times.partition_point(|&v| v < t);
    if after == 0 {
        return 0;
    }
    if after == times.len() {
        return times.len() - 1;
    }
    if times[after] - t < t - times[after - 1] {
        after
    } else {
        after - 1
    }
}

fn rows<T: Copy>(values: &[T], width: usize, pick: &[usize]) -> Vec<T> {
    let mut out = Vec::with_capacity(pick.len() * width);
    for &i in pick {
        out.extend_from_slice(&values[i * width..(i + 1) * width]);
    }
    out
}

fn to_f64(v: &[f32]) -> Vec<f64> {
    v.iter().map(|&x| f64::from(x)).collect()
}

fn to_f32(v: &[f64]) -> Vec<f32> {
    v.iter().map(|&x| x as f32).collect()
}

/// The repaired episode. `expected` is the source's interval in seconds. Episodes without
/// timestamps, and `Repair::None`, come back unchanged.
pub fn apply(
    episode: Episode,
    repair: &Repair,
    channels: &[ChannelInfo],
    expected: f64,
) -> Episode {
    let Some(stamps) = episode.timestamps.as_deref() else {
        return episode;
    };
    let first = stamps.first().copied().unwrap_or(0.0);
    let (times, kept) = drop_repeats(stamps);
    let steps = match repair {
        Repair::None | Repair::Exclude => return episode,
        Repair::Regrid { steps } | Repair::Resample { steps, .. } => *steps,
    };
    let grid: Vec<f64> = (0..steps).map(|k| first + k as f64 * expected).collect();
    let mut out = Vec::with_capacity(channels.len());
    for (ch, data) in channels.iter().zip(&episode.channels) {
        let width = ch.width();
        out.push(match (data, repair) {
            (ChannelData::Lowdim(v), Repair::Regrid { .. }) => {
                let y = to_f64(&rows(v, width, &kept));
                ChannelData::Lowdim(to_f32(&spline::interpolate(&times, &y, width, &grid)))
            }
            (ChannelData::Lowdim(v), Repair::Resample { method, .. }) => {
                let y = to_f64(&rows(v, width, &kept));
                ChannelData::Lowdim(to_f32(&resample::resample(&y, width, steps, *method)))
            }
            (ChannelData::Image(v), Repair::Regrid { .. }) => {
                let pick: Vec<usize> = grid
                    .iter()
                    .map(|&t| kept[nearest_time(&times, t)])
                    .collect();
                ChannelData::Image(rows(v, width, &pick))
            }
            (ChannelData::Image(v), Repair::Resample { .. }) => {
                let n = kept.len();
                let pick: Vec<usize> = (0..steps)
                    .map(|k| kept[resample::nearest(k, n, steps)])
                    .collect();
                ChannelData::Image(rows(v, width, &pick))
            }
            (_, Repair::None | Repair::Exclude) => unreachable!("returned above"),
        });
    }
    Episode {
        id: episode.id,
        len: steps,
        timestamps: Some(grid),
        channels: out,
        packets: Default::default(),
    }
}

/// Converts a whole (repaired) episode to `steps` steps for a profile whose rate does not divide
/// the source's: numbers by `method`, images by the nearest frame.
pub fn convert_rate(
    values: &ChannelData,
    width: usize,
    steps: usize,
    method: crate::spec::ResampleMethod,
) -> ChannelData {
    match values {
        ChannelData::Lowdim(v) => ChannelData::Lowdim(to_f32(&resample::resample(
            &to_f64(v),
            width,
            steps,
            method,
        ))),
        ChannelData::Image(v) => {
            let n = v.len() / width.max(1);
            let pick: Vec<usize> = (0..steps).map(|k| resample::nearest(k, n, steps)).collect();
            ChannelData::Image(rows(v, width, &pick))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::nearest_time;

    #[test]
    fn nearest_times() {
        let t = [0.0, 0.25, 0.75];
        assert_eq!(nearest_time(&t, -1.0), 0);
        assert_eq!(nearest_time(&t, 0.1), 0);
        assert_eq!(nearest_time(&t, 0.5), 1);
        assert_eq!(nearest_time(&t, 0.51), 2);
        assert_eq!(nearest_time(&t, 9.0), 2);
    }
}
