//! Camera frames resized at build time (`[profiles.<name>.cameras.<channel>] size = [H, W]`),
//! the way Diffusion Policy resizes its real-robot cameras while it builds a replay buffer
//! (`diffusion_policy/common/cv2_util.py`, `get_image_transform`):
//!
//! 1. Scale to **cover** the output, keeping the aspect ratio: when the source is at least as
//!    wide as the output (`iw / ih >= ow / oh`), the height becomes `oh` and the width
//!    `ceil(oh / ih × iw)`; otherwise the width becomes `ow` and the height
//!    `ceil(ow / iw × ih)` (the same `f64` operations, so the same rounding).
//! 2. Interpolate as OpenCV's `cv2.resize` does: `INTER_AREA` when that side shrinks
//!    ([`area`]), `INTER_LINEAR` when it grows ([`linear`]); the same size is a copy.
//! 3. Crop the centre: rows from `(rh - oh) / 2`, columns from `(rw - ow) / 2` (floor).
//!
//! Frames are `uint8` (H, W, C), row-major; every frame of a run goes through the same tables,
//! so the bytes depend only on the frame and the two sizes (never on threads).
//!
//! - `area`: OpenCV's area average (whole and fractional factors).
//! - `linear`: OpenCV's fixed-point bilinear interpolation, half-pixel centres.

mod area;
mod linear;

/// How the covering size is reached.
#[derive(Debug, Clone, PartialEq)]
enum Kernel {
    /// The covering size is the source's.
    Copy,
    Area(area::Area),
    Linear(linear::Linear),
}

/// One camera's resize: from the source's (H, W) to the stored (H, W), colours unchanged.
#[derive(Debug, Clone, PartialEq)]
pub struct Resize {
    src: [usize; 2],
    /// The covering size (before the crop).
    scaled: [usize; 2],
    /// Where the crop starts in the covering frame: row, column.
    offset: [usize; 2],
    out: [usize; 2],
    colors: usize,
    kernel: Kernel,
}

impl Resize {
    /// Diffusion Policy's transform from `src` (H, W) to `out` (H, W), `colors` values per
    /// pixel. Both sizes must be positive.
    pub fn cover(src: [usize; 2], out: [usize; 2], colors: usize) -> Resize {
        let [ih, iw] = src.map(|v| v as f64);
        let [oh, ow] = out.map(|v| v as f64);
        let (scaled, grows) = if iw / ih >= ow / oh {
            ([out[0], (oh / ih * iw).ceil() as usize], out[0] > src[0])
        } else {
            ([(ow / iw * ih).ceil() as usize, out[1]], out[1] > src[1])
        };
        let kernel = if scaled == src {
            Kernel::Copy
        } else if grows {
            Kernel::Linear(linear::Linear::new(src, scaled))
        } else {
            Kernel::Area(area::Area::new(src, scaled, colors))
        };
        Resize {
            src,
            scaled,
            offset: [(scaled[0] - out[0]) / 2, (scaled[1] - out[1]) / 2],
            out,
            colors,
            kernel,
        }
    }

    /// The stored per-step shape (H, W, C).
    pub fn shape(&self) -> [usize; 3] {
        [self.out[0], self.out[1], self.colors]
    }

    /// Whether frames come out as they went in (the stored size is the source's).
    pub fn is_identity(&self) -> bool {
        self.kernel == Kernel::Copy && self.out == self.src
    }

    /// The covering size before the crop (H, W), as `chunkc plan` describes it.
    pub fn scaled(&self) -> [usize; 2] {
        self.scaled
    }

    /// `area` (shrinking), `linear` (enlarging) or `copy` (the same covering size: only
    /// cropped), as `chunkc plan` names the interpolation.
    pub fn method(&self) -> &'static str {
        match self.kernel {
            Kernel::Copy => "copy",
            Kernel::Area(_) => "area",
            Kernel::Linear(_) => "linear",
        }
    }

    /// Bytes of one source frame.
    pub fn src_bytes(&self) -> usize {
        self.src[0] * self.src[1] * self.colors
    }

    /// Bytes of one stored frame.
    pub fn out_bytes(&self) -> usize {
        self.out[0] * self.out[1] * self.colors
    }

    /// Every frame of `frames` (source frames back to back) resized, back to back.
    pub fn frames(&self, frames: &[u8]) -> Vec<u8> {
        let n = frames.len() / self.src_bytes().max(1);
        let mut out = vec![0u8; n * self.out_bytes()];
        let mut scratch = Vec::new();
        for (src, dst) in frames
            .chunks_exact(self.src_bytes())
            .zip(out.chunks_exact_mut(self.out_bytes()))
        {
            self.frame(src, dst, &mut scratch);
        }
        out
    }

    /// One frame; `scratch` holds the covering frame when it must be cropped.
    pub fn frame(&self, src: &[u8], dst: &mut [u8], scratch: &mut Vec<u8>) {
        let covering = self.scaled[0] * self.scaled[1] * self.colors;
        let cropped = self.scaled != self.out;
        let target: &mut [u8] = if cropped {
            scratch.resize(covering, 0);
            scratch
        } else {
            dst
        };
        match &self.kernel {
            Kernel::Copy => target.copy_from_slice(src),
            Kernel::Area(a) => a.apply(src, self.src, target, self.scaled, self.colors),
            Kernel::Linear(l) => l.apply(src, self.src, target, self.colors),
        }
        if cropped {
            let row = self.scaled[1] * self.colors;
            let (width, left) = (self.out[1] * self.colors, self.offset[1] * self.colors);
            for (y, out) in dst.chunks_exact_mut(width).enumerate() {
                let start = (self.offset[0] + y) * row + left;
                out.copy_from_slice(&scratch[start..start + width]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_sizes_and_crops_follow_diffusion_policy() {
        // 480x640 to 240x320: the same aspect, a 2x box average, no crop.
        let r = Resize::cover([480, 640], [240, 320], 3);
        assert_eq!((r.scaled, r.offset), ([240, 320], [0, 0]));
        // To a square: the height covers, the width is cropped in the middle.
        let r = Resize::cover([480, 640], [120, 120], 3);
        assert_eq!((r.scaled, r.offset), ([120, 160], [0, 20]));
        // A taller output: the width covers; ceil(100 / 640 × 480) = 75 rows, 5 cropped above.
        let r = Resize::cover([480, 640], [64, 100], 3);
        assert_eq!((r.scaled, r.offset), ([75, 100], [5, 0]));
        // Non-integer widths round up: ceil(100 / 480 × 640) = ceil(133.33) = 134, offset 17.
        let r = Resize::cover([480, 640], [100, 100], 1);
        assert_eq!((r.scaled, r.offset), ([100, 134], [0, 17]));
        // The same size is a copy; the same height with a narrower width only crops.
        assert!(Resize::cover([96, 96], [96, 96], 3).is_identity());
        let r = Resize::cover([4, 6], [4, 2], 1);
        assert_eq!((&r.kernel, r.offset), (&Kernel::Copy, [0, 2]));
        let frame: Vec<u8> = (0..24).collect();
        assert_eq!(r.frames(&frame), [2, 3, 8, 9, 14, 15, 20, 21]);
    }

    #[test]
    fn a_small_frame_by_hand() {
        // 2x4 RGB to 1x1: covers at 1x2 (a 2x2 box average per colour), then the crop keeps
        // the column at offset (2 - 1) / 2 = 0, the left one.
        let mut frame = Vec::new();
        for y in 0..2u8 {
            for x in 0..4u8 {
                frame.extend([10 * x + y, 100, 200 + x]);
            }
        }
        let r = Resize::cover([2, 4], [1, 1], 3);
        assert_eq!((r.scaled, r.offset), ([1, 2], [0, 0]));
        // Left box: x 0..2, y 0..2: red (0 + 1 + 10 + 11 + 2) >> 2 = 6, green 100, blue
        // (200 + 201 + 200 + 201 + 2) >> 2 = 201.
        assert_eq!(r.frames(&frame), [6, 100, 201]);
        // Two frames back to back come out back to back.
        let two = [frame.clone(), frame].concat();
        assert_eq!(r.frames(&two), [6, 100, 201, 6, 100, 201]);
    }
}
