//! Growing by bilinear interpolation, as OpenCV's `cv2.resize(..., interpolation=
//! cv2.INTER_LINEAR)` does it for `uint8` frames.
//!
//! Pixel centres are at half-integers: destination pixel `d` samples the source at
//! `(d + 0.5) × scale - 0.5` (`scale = source / destination`), computed in `f32` as OpenCV
//! does. The weights are fixed point, 11 bits (`round(w × 2048)`, rounded half to even), and
//! the arithmetic is integer: horizontal sums of two source pixels (`i32`, 2048 = 1), then the
//! two rows weighted again and brought back to 8 bits. The vertical step follows OpenCV's vector
//! path (`((a >> 4) × b0 >> 16) + ((c >> 4) × b1 >> 16)`, then `(x + 2) >> 2`), which covers
//! whole rows (measured against `cv2.resize` 4.14: its last vector overlaps the one before);
//! rows narrower than a vector take its scalar path (`(a × b0 + c × b1 + 2^21) >> 22`). The two
//! agree within one level. Outside the source, the edge pixel repeats.

/// Fixed-point one of the weights (OpenCV's `INTER_RESIZE_COEF_SCALE`).
const ONE: i32 = 2048;

/// Rows of fewer elements than this take OpenCV's scalar vertical step (a 128-bit vector of
/// 16-bit values).
const LANES: usize = 8;

/// One destination index along an axis: the first of its two source indices and their
/// fixed-point weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Sample {
    pub first: i64,
    pub weights: [i32; 2],
}

/// The samples of one axis: `source` pixels to `dest`. `clamp` keeps the first index inside the
/// source with its weight moved onto it (OpenCV does so horizontally); without it, the indices
/// are clipped where they are read (vertically).
pub(super) fn samples(source: usize, dest: usize, clamp: bool) -> Vec<Sample> {
    // OpenCV's scale: the inverse of the inverse scale, both in f64.
    let scale = 1.0 / (dest as f64 / source as f64);
    (0..dest)
        .map(|d| {
            let mut f = ((d as f64 + 0.5) * scale - 0.5) as f32;
            let mut first = f.floor() as i64;
            f -= first as f32;
            if clamp {
                if first < 0 {
                    (f, first) = (0.0, 0);
                }
                if first >= source as i64 - 1 {
                    (f, first) = (0.0, source as i64 - 1);
                }
            }
            let weight = |w: f32| (w * ONE as f32).round_ties_even() as i32;
            Sample {
                first,
                weights: [weight(1.0 - f), weight(f)],
            }
        })
        .collect()
}

/// Bilinear tables for one source size and one destination size.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Linear {
    x: Vec<Sample>,
    y: Vec<Sample>,
}

impl Linear {
    /// The tables for `src` (H, W) resized to `dst` (H, W).
    pub fn new(src: [usize; 2], dst: [usize; 2]) -> Linear {
        Linear {
            x: samples(src[1], dst[1], true),
            y: samples(src[0], dst[0], false),
        }
    }

    /// Resizes one frame `src` ((H, W, C) row-major) into `dst` ((H', W', C)).
    pub fn apply(&self, src: &[u8], src_hw: [usize; 2], dst: &mut [u8], c: usize) {
        let (h, w) = (src_hw[0] as i64, src_hw[1]);
        let width = self.x.len() * c;
        let horizontal = |row: usize, out: &mut Vec<i32>| {
            let row = &src[row * w * c..(row + 1) * w * c];
            out.clear();
            for s in &self.x {
                let at = s.first as usize * c;
                for k in 0..c {
                    // The clamped last column has weight 0 on a neighbour it must not read.
                    let next = if s.weights[1] == 0 {
                        0
                    } else {
                        row[at + c + k]
                    };
                    out.push(
                        i32::from(row[at + k]) * s.weights[0] + i32::from(next) * s.weights[1],
                    );
                }
            }
        };
        let (mut upper, mut lower) = (Vec::with_capacity(width), Vec::with_capacity(width));
        let mut rows: Option<(usize, usize)> = None;
        let vector = width >= LANES;
        for (dy, s) in self.y.iter().enumerate() {
            let clip = |r: i64| r.clamp(0, h - 1) as usize;
            let (r0, r1) = (clip(s.first), clip(s.first + 1));
            if rows != Some((r0, r1)) {
                if rows.map(|(_, b)| b) == Some(r0) {
                    std::mem::swap(&mut upper, &mut lower);
                } else {
                    horizontal(r0, &mut upper);
                }
                horizontal(r1, &mut lower);
                rows = Some((r0, r1));
            }
            let [b0, b1] = s.weights;
            let out = &mut dst[dy * width..(dy + 1) * width];
            for (i, o) in out.iter_mut().enumerate() {
                let (a, b) = (upper[i], lower[i]);
                let v = if vector {
                    ((((a >> 4) * b0) >> 16) + (((b >> 4) * b1) >> 16) + 2) >> 2
                } else {
                    (a * b0 + b * b1 + (1 << 21)) >> 22
                };
                *o = v.clamp(0, 255) as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doubling_samples_at_half_pixels() {
        // 2 -> 4: centres at -0.25, 0.25, 0.75, 1.25: weights 1/4 and 3/4, edges repeated.
        let s = samples(2, 4, true);
        let got: Vec<(i64, [i32; 2])> = s.iter().map(|s| (s.first, s.weights)).collect();
        assert_eq!(
            got,
            [
                (0, [2048, 0]),
                (0, [1536, 512]),
                (0, [512, 1536]),
                (1, [2048, 0])
            ]
        );
        // Vertically the first index is not clamped: -1 with weights 1/4, 3/4 of row 0 twice.
        let s = samples(2, 4, false);
        assert_eq!((s[0].first, s[0].weights), (-1, [512, 1536]));
    }

    #[test]
    fn a_doubled_ramp_by_hand() {
        // One row 0, 100 doubled: 0, 25, 75, 100.
        let mut dst = [0u8; 4];
        Linear::new([1, 2], [1, 4]).apply(&[0, 100], [1, 2], &mut dst, 1);
        assert_eq!(dst, [0, 25, 75, 100]);
    }
}
