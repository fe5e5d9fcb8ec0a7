//! Hierarchical chunks: a coarse chunk of `coarse` steps starting at `t`, cut into fine chunks of
//! `fine` steps. Sample `(t, sub = j)` is the fine chunk starting at `t + j*fine`; its rows stop
//! at the end of the coarse chunk and of the episode (padding, with a mask, beyond).

use super::{Sample, Window};
use crate::spec::Padding;

pub fn samples(
    len: usize,
    coarse: usize,
    fine: usize,
    stride: usize,
    padding: Padding,
) -> Vec<Sample> {
    let coarse_windows = Window {
        chunk: coarse,
        obs_history: 1,
        lead: 0,
        padding,
        stride,
        max_pad_after: None,
    };
    let per_coarse = coarse.div_ceil(fine);
    let mut out = Vec::new();
    for s in coarse_windows.samples(len) {
        for j in 0..per_coarse {
            if s.t + j * fine < len {
                out.push(Sample {
                    t: s.t,
                    limit: coarse,
                    sub: j,
                });
            }
        }
    }
    out
}

/// Rows of the fine chunk of a sample, `None` where padded.
pub fn fine_rows(s: Sample, fine: usize, len: usize) -> impl Iterator<Item = Option<usize>> {
    let start = s.t + s.sub * fine;
    let end = (s.t + s.limit).min(len);
    (start..start + fine).map(move |r| (r < end).then_some(r))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator, so the property test needs no extra crate.
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self, n: usize) -> usize {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 33) % n as u64) as usize
        }
    }

    #[test]
    fn fine_chunks_stay_inside_their_coarse_chunk_and_episode() {
        let mut rng = Lcg(7);
        for _ in 0..2000 {
            let len = rng.next(120);
            let fine = 1 + rng.next(12);
            let coarse = fine + rng.next(40);
            let stride = 1 + rng.next(10);
            let padding = [Padding::Edge, Padding::Mask, Padding::Truncate][rng.next(3)];
            for s in samples(len, coarse, fine, stride, padding) {
                let start = s.t + s.sub * fine;
                assert!(start < len && start < s.t + coarse, "fine start outside");
                for r in fine_rows(s, fine, len).flatten() {
                    assert!(r >= s.t && r < s.t + coarse && r < len);
                }
                assert!(fine_rows(s, fine, len).next().unwrap().is_some());
            }
        }
    }

    #[test]
    fn every_fine_chunk_of_a_full_coarse_chunk() {
        let s = samples(100, 40, 10, 40, Padding::Edge);
        assert_eq!(s.len(), 4 + 4 + 2); // coarse chunks at 0, 40, 80 (the last has 20 steps)
        assert_eq!((s[5].t, s[5].sub), (40, 1));
    }
}
