//! Shrinking by area averaging, as OpenCV's `cv2.resize(..., interpolation=cv2.INTER_AREA)`
//! does it for `uint8` frames when neither side grows.
//!
//! Two cases, as in OpenCV (`imgproc/src/resize.cpp`):
//! - **Integer factors** (both source/destination ratios whole numbers): a box average of the
//!   `fx × fy` source pixels under each destination pixel. OpenCV's 2×2 case rounds half up
//!   (`(a + b + c + d + 2) >> 2`, its vectorised path); every other factor multiplies the `i32`
//!   sum by the `f32` reciprocal of the area and rounds half to even.
//! - **Fractional factors**: each destination pixel is the average of the source area it covers,
//!   a source pixel cut by a cell border counting by the fraction inside the cell. The weights
//!   are computed in `f64` and kept as `f32`, the sums are `f32`, a row at a time (horizontal
//!   sums of one source row, then added into the destination row with the row's weight), and the
//!   result is rounded half to even: the same operations in the same order as OpenCV's, so that
//!   the bytes agree (the Python tests compare with `cv2.resize`).

/// One weighted tap of the area table: destination index `di` (an element index, colour
/// included, for the horizontal table; a row for the vertical one) takes source index `si`
/// with weight `alpha`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Tap {
    pub di: usize,
    pub si: usize,
    pub alpha: f32,
}

/// The taps of one axis of `source` elements shrunk to `dest` by `scale = source / dest` (as
/// OpenCV computes it: `1 / (dest / source)`), `colors` values per element. A cell starts at
/// `d × scale`; source pixels the cell covers whole weigh `1 / width`, the partly covered ones
/// at its ends their covered fraction (ignored below 1e-3); `width` is the cell's width, cut at
/// the source's end.
pub(super) fn taps(source: usize, dest: usize, colors: usize, scale: f64) -> Vec<Tap> {
    let mut out = Vec::with_capacity(2 * source);
    let last = source as i64 - 1;
    for d in 0..dest {
        let start = d as f64 * scale;
        let end = start + scale;
        let width = scale.min(source as f64 - start);
        let mut first = start.ceil() as i64;
        let stop = (end.floor() as i64).min(last);
        first = first.min(stop);
        let tap = |s: i64, alpha: f64| Tap {
            di: d * colors,
            si: s as usize * colors,
            alpha: alpha as f32,
        };
        if first as f64 - start > 1e-3 {
            out.push(tap(first - 1, (first as f64 - start) / width));
        }
        for s in first..stop {
            out.push(tap(s, 1.0 / width));
        }
        if end - stop as f64 > 1e-3 {
            out.push(tap(stop, (end - stop as f64).min(1.0).min(width) / width));
        }
    }
    out
}

/// Area tables for one source size and one destination size.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Area {
    /// Whole factors `fx`, `fy`.
    Box { fx: usize, fy: usize },
    /// Fractional factors: the horizontal taps (element indices) and the vertical taps (rows).
    Weighted { x: Vec<Tap>, y: Vec<Tap> },
}

impl Area {
    /// The tables for `src` (H, W) shrunk to `dst` (H, W), `colors` values per pixel. Each
    /// destination side must be at most its source side.
    pub fn new(src: [usize; 2], dst: [usize; 2], colors: usize) -> Area {
        debug_assert!(dst[0] <= src[0] && dst[1] <= src[1] && dst[0] > 0 && dst[1] > 0);
        // OpenCV's scale: the inverse of the inverse scale, both in f64.
        let scale_y = 1.0 / (dst[0] as f64 / src[0] as f64);
        let scale_x = 1.0 / (dst[1] as f64 / src[1] as f64);
        let (iy, ix) = (scale_y.round_ties_even(), scale_x.round_ties_even());
        let whole = (scale_x - ix).abs() < f64::EPSILON && (scale_y - iy).abs() < f64::EPSILON;
        if whole {
            Area::Box {
                fx: ix as usize,
                fy: iy as usize,
            }
        } else {
            Area::Weighted {
                x: taps(src[1], dst[1], colors, scale_x),
                y: taps(src[0], dst[0], 1, scale_y),
            }
        }
    }

    /// Shrinks one frame `src` (H, W, C row-major) into `dst` ((H', W', C)).
    pub fn apply(
        &self,
        src: &[u8],
        src_hw: [usize; 2],
        dst: &mut [u8],
        dst_hw: [usize; 2],
        c: usize,
    ) {
        match self {
            Area::Box { fx, fy } => box_average(src, src_hw[1], dst, dst_hw, c, *fx, *fy),
            Area::Weighted { x, y } => weighted(src, src_hw[1], dst, dst_hw[1], c, x, y),
        }
    }
}

/// The box average of whole factors `fx × fy`.
fn box_average(
    src: &[u8],
    src_w: usize,
    dst: &mut [u8],
    dst_hw: [usize; 2],
    c: usize,
    fx: usize,
    fy: usize,
) {
    let src_row = src_w * c;
    let dst_row = dst_hw[1] * c;
    if fx == 2 && fy == 2 {
        return halve(src, src_row, dst, dst_row, c);
    }
    let area = (fx * fy) as i32;
    let reciprocal = 1.0f32 / area as f32;
    for dy in 0..dst_hw[0] {
        let top = dy * fy * src_row;
        for dx in 0..dst_hw[1] {
            for k in 0..c {
                let mut sum = 0i32;
                for sy in 0..fy {
                    let row = top + sy * src_row;
                    for sx in 0..fx {
                        sum += i32::from(src[row + (dx * fx + sx) * c + k]);
                    }
                }
                dst[dy * dst_row + dx * c + k] = saturate(sum as f32 * reciprocal);
            }
        }
    }
}

/// The 2×2 box average, the common case (a 640x480 camera stored at 320x240), a pair of rows
/// at a time: `(a + b + c + d + 2) >> 2`, OpenCV's rounding for it.
fn halve(src: &[u8], src_row: usize, dst: &mut [u8], dst_row: usize, c: usize) {
    for (dy, out) in dst.chunks_exact_mut(dst_row).enumerate() {
        let upper = &src[2 * dy * src_row..(2 * dy + 1) * src_row];
        let lower = &src[(2 * dy + 1) * src_row..(2 * dy + 2) * src_row];
        let pairs = upper.chunks_exact(2 * c).zip(lower.chunks_exact(2 * c));
        for (o, (a, b)) in out.chunks_exact_mut(c).zip(pairs) {
            for k in 0..c {
                let sum =
                    u16::from(a[k]) + u16::from(a[c + k]) + u16::from(b[k]) + u16::from(b[c + k]);
                o[k] = ((sum + 2) >> 2) as u8;
            }
        }
    }
}

/// The weighted area average: per source row, its horizontal sums; added into the destination
/// row with the row's weight; a destination row is rounded when the next one starts.
fn weighted(
    src: &[u8],
    src_w: usize,
    dst: &mut [u8],
    dst_w: usize,
    c: usize,
    x: &[Tap],
    y: &[Tap],
) {
    let width = dst_w * c;
    let src_row = src_w * c;
    let mut buf = vec![0f32; width];
    let mut sum = vec![0f32; width];
    let Some(first) = y.first() else { return };
    let mut prev = first.di;
    for t in y {
        let row = &src[t.si * src_row..(t.si + 1) * src_row];
        buf.fill(0.0);
        for tap in x {
            let from = &row[tap.si..tap.si + c];
            let to = &mut buf[tap.di..tap.di + c];
            for (b, &s) in to.iter_mut().zip(from) {
                *b += f32::from(s) * tap.alpha;
            }
        }
        if t.di != prev {
            let out = &mut dst[prev * width..(prev + 1) * width];
            for ((o, s), b) in out.iter_mut().zip(sum.iter_mut()).zip(&buf) {
                *o = saturate(*s);
                *s = t.alpha * b;
            }
            prev = t.di;
        } else {
            for (s, b) in sum.iter_mut().zip(&buf) {
                *s += t.alpha * b;
            }
        }
    }
    let out = &mut dst[prev * width..(prev + 1) * width];
    for (o, s) in out.iter_mut().zip(&sum) {
        *o = saturate(*s);
    }
}

/// OpenCV's `saturate_cast<uchar>(float)`: round half to even, then clamp to 0..=255.
pub(super) fn saturate(v: f32) -> u8 {
    v.round_ties_even().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_factors_average_boxes() {
        // 2x2 rounds half up (OpenCV's vector path): (1 + 2 + 3 + 4 + 2) >> 2 = 3 (2.5 up).
        let src = [1, 2, 5, 5, 3, 4, 5, 6];
        let area = Area::new([2, 4], [1, 2], 1);
        assert_eq!(area, Area::Box { fx: 2, fy: 2 });
        let mut dst = [0u8; 2];
        area.apply(&src, [2, 4], &mut dst, [1, 2], 1);
        assert_eq!(dst, [3, 5]);
        // 3x1: the f32 mean rounded half to even: (1 + 2 + 4) / 3 = 2.33 -> 2; (2+2+3)/3=2.33.
        let area = Area::new([1, 6], [1, 2], 1);
        let mut dst = [0u8; 2];
        area.apply(&[1, 2, 4, 2, 2, 3], [1, 6], &mut dst, [1, 2], 1);
        assert_eq!(dst, [2, 2]);
    }

    #[test]
    fn fractional_taps_split_the_cut_pixel() {
        // 3 -> 2: scale 1.5; cell 0 is [0, 1.5): pixel 0 whole, half of pixel 1; cell 1 is
        // [1.5, 3): half of pixel 1, pixel 2 whole. Weights over the cell width 1.5.
        let t = taps(3, 2, 1, 1.5);
        let w: Vec<(usize, usize, f32)> = t.iter().map(|t| (t.di, t.si, t.alpha)).collect();
        let (whole, half) = ((1.0f64 / 1.5) as f32, (0.5f64 / 1.5) as f32);
        assert_eq!(
            w,
            [(0, 0, whole), (0, 1, half), (1, 1, half), (1, 2, whole)]
        );
    }

    #[test]
    fn fractional_shrink_by_hand() {
        // A 3x3 grey frame to 2x2. Row weights as the columns': 2/3 and 1/3.
        // Column sums of row r: left = 2/3 a + 1/3 b, right = 1/3 b + 2/3 c.
        let src = [
            0, 30, 60, //
            90, 120, 150, //
            180, 210, 240,
        ];
        let area = Area::new([3, 3], [2, 2], 1);
        assert!(matches!(area, Area::Weighted { .. }));
        let mut dst = [0u8; 4];
        area.apply(&src, [3, 3], &mut dst, [2, 2], 1);
        // Top-left: 2/3 (2/3·0 + 1/3·30) + 1/3 (2/3·90 + 1/3·120) = 2/3·10 + 1/3·100 = 40.
        // Top-right: 2/3·50 + 1/3·140 = 80; bottom-left: 1/3·100 + 2/3·190 = 160; bottom-right:
        // 1/3·140 + 2/3·230 = 200.
        assert_eq!(dst, [40, 80, 160, 200]);
    }
}
