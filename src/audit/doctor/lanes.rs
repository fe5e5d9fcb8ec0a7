//! The lag fits' inner loop: one column's dot products with two series at sixteen shifts, in
//! single precision eight lanes wide, on every machine the same bits.
//!
//! The products are summed per lane in `f32` over blocks of [`BLOCK`] rows, and each block's
//! lanes are added into `f64` totals: the single-precision sums stay short (a lane adds at most
//! sixteen products), so the totals lose nothing the `f32` inputs had. The lanes, the blocks
//! and every addition are in one fixed order, written out here: the compiler never reorders
//! floating-point additions and never fuses a multiply and an add on its own, so the AVX2 copy
//! of the kernel (chosen at run time) and the baseline (SSE2) one compute the same bits, and a
//! dataset's doctor report does not depend on the machine that built it.

/// The lanes of one accumulator: eight `f32`, one AVX2 register (two SSE2 ones).
pub const LANES: usize = 8;
/// Rows per block: each lane sums `BLOCK / LANES` products in single precision.
const BLOCK: usize = 128;
/// The shifts one call computes.
pub const SHIFTS: usize = 16;

/// `(Σₜ x[k + t]·p[t], Σₜ x[k + t]·q[t])` for every shift `k` in `0..SHIFTS`, over `t` in
/// `0..p.len()`. `p` and `q` are equally long, a multiple of [`LANES`] (pad them with zeros), and
/// `x` holds at least `p.len() + SHIFTS - 1` values (finite: a padded row adds `x·0`).
pub fn shifted_dots(x: &[f32], p: &[f32], q: &[f32]) -> ([f64; SHIFTS], [f64; SHIFTS]) {
    assert!(p.len() == q.len() && p.len().is_multiple_of(LANES) && x.len() + 1 >= p.len() + SHIFTS);
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { shifted_dots_avx2(x, p, q) };
    }
    shifted_dots_baseline(x, p, q)
}

/// The kernel for the build's baseline target (SSE2 on x86-64): two shifts at a time, so that
/// their accumulators fit in the sixteen SSE registers.
fn shifted_dots_baseline(x: &[f32], p: &[f32], q: &[f32]) -> ([f64; SHIFTS], [f64; SHIFTS]) {
    kernel::<2>(x, p, q)
}

/// The kernel compiled for AVX2 (no FMA: a fused multiply-add rounds once where the baseline
/// rounds twice): four shifts at a time, eight accumulators in the sixteen YMM registers.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn shifted_dots_avx2(x: &[f32], p: &[f32], q: &[f32]) -> ([f64; SHIFTS], [f64; SHIFTS]) {
    kernel::<4>(x, p, q)
}

/// The kernel, `G` shifts per sweep over a block (each row of `p` and `q` loaded once for `G`
/// shifts). The grouping changes no sum: each shift's lanes add the same products in the same
/// order whatever `G`.
#[inline(always)]
fn kernel<const G: usize>(x: &[f32], p: &[f32], q: &[f32]) -> ([f64; SHIFTS], [f64; SHIFTS]) {
    let len = p.len();
    // Per shift, four f64 lanes: lanes l and l + 4 of each block go into lane l.
    let mut tp = [[0.0f64; 4]; SHIFTS];
    let mut tq = [[0.0f64; 4]; SHIFTS];
    let mut start = 0;
    while start < len {
        let end = (start + BLOCK).min(len);
        let (pb, qb) = (&p[start..end], &q[start..end]);
        for k0 in (0..SHIFTS).step_by(G) {
            let mut ap = [[0.0f32; LANES]; G];
            let mut aq = [[0.0f32; LANES]; G];
            let xs: [&[f32]; G] = std::array::from_fn(|g| &x[k0 + g + start..k0 + g + end]);
            for (c, (pc, qc)) in pb
                .chunks_exact(LANES)
                .zip(qb.chunks_exact(LANES))
                .enumerate()
            {
                for g in 0..G {
                    let xc = &xs[g][c * LANES..c * LANES + LANES];
                    for l in 0..LANES {
                        ap[g][l] += xc[l] * pc[l];
                        aq[g][l] += xc[l] * qc[l];
                    }
                }
            }
            for g in 0..G {
                fold(&mut tp[k0 + g], &ap[g]);
                fold(&mut tq[k0 + g], &aq[g]);
            }
        }
        start = end;
    }
    let total = |t: &[f64; 4]| (t[0] + t[1]) + (t[2] + t[3]);
    (
        std::array::from_fn(|k| total(&tp[k])),
        std::array::from_fn(|k| total(&tq[k])),
    )
}

/// Adds a block's eight `f32` lanes into four `f64` ones (lanes l and l + 4 into l).
#[inline(always)]
fn fold(total: &mut [f64; 4], lanes: &[f32; LANES]) {
    for l in 0..4 {
        total[l] += f64::from(lanes[l]) + f64::from(lanes[l + 4]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 3.0
            })
            .collect()
    }

    /// The AVX2 copy and the baseline give the same bits, at lengths that end mid-block.
    #[test]
    fn avx2_and_baseline_agree_bit_for_bit() {
        for (len, seed) in [(8, 1), (120, 2), (128, 3), (384, 4), (1000, 5)] {
            let x = random(len + SHIFTS - 1, seed);
            let (p, q) = (random(len, seed + 10), random(len, seed + 20));
            let base = shifted_dots_baseline(&x, &p, &q);
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                let avx2 = unsafe { shifted_dots_avx2(&x, &p, &q) };
                let bits = |v: &[f64; SHIFTS]| v.map(f64::to_bits);
                assert_eq!(bits(&base.0), bits(&avx2.0), "len {len}");
                assert_eq!(bits(&base.1), bits(&avx2.1), "len {len}");
            }
            // And both are the dot products, to single precision.
            for k in 0..SHIFTS {
                let exact = |v: &[f32]| -> f64 {
                    (0..len)
                        .map(|t| f64::from(x[k + t]) * f64::from(v[t]))
                        .sum()
                };
                let scale: f64 = (0..len).map(|t| f64::from(x[k + t].abs()) * 1.5).sum();
                assert!((base.0[k] - exact(&p)).abs() <= 1e-6 * scale, "len {len}");
                assert!((base.1[k] - exact(&q)).abs() <= 1e-6 * scale, "len {len}");
            }
        }
    }
}
