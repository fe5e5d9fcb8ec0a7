//! The memory a build keeps its low-dimensional values in: `CHUNKC_SPILL_BYTES` (the tests force
//! spilling with it), else `chunkc build --memory` / `[build] memory`, else a quarter of the
//! memory available when the build starts. The row stores share it: the smallest keep their
//! values in memory while the budget lasts, and the others spill to the staging directory. The
//! outputs are the same bytes either way.

/// The budget when neither the spec nor the command line sets one and the available memory is
/// unknown.
const FALLBACK: usize = 1 << 30;

/// The default budget's bounds: a quarter of the available memory, within these.
const DEFAULT_RANGE: (usize, usize) = (256 << 20, 16 << 30);

/// The build's budget for values kept in memory; `asked`: `--memory` or `[build] memory`.
pub fn budget(asked: Option<u64>) -> usize {
    if let Some(bytes) = std::env::var("CHUNKC_SPILL_BYTES")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        return bytes;
    }
    match asked {
        Some(bytes) => bytes as usize,
        None => available().map_or(FALLBACK, |a| {
            (a / 4).clamp(DEFAULT_RANGE.0, DEFAULT_RANGE.1)
        }),
    }
}

/// `MemAvailable` of `/proc/meminfo`, in bytes (None elsewhere than Linux).
fn available() -> Option<usize> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Each store's budget (same shape as `values`: per rate, per channel, the values it will
/// hold): its own size when it is among the smallest stores that fit in `total` together, else
/// `total` (it spills, a block of at most 8 MiB at a time; see `store`).
pub fn share(total: usize, values: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let mut order: Vec<(usize, usize, usize)> = (values.iter().enumerate())
        .flat_map(|(r, rate)| rate.iter().enumerate().map(move |(c, &v)| (v * 4, r, c)))
        .collect();
    order.sort_unstable();
    let mut out: Vec<Vec<usize>> = values.iter().map(|r| vec![total; r.len()]).collect();
    let mut left = total;
    for (bytes, r, c) in order {
        if bytes > left {
            break;
        }
        left -= bytes;
        out[r][c] = bytes;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smallest_stores_keep_their_values_while_the_budget_lasts() {
        // Bytes 400, 40, 4000 | 4, 0: a budget of 500 keeps all but the 4000 in memory.
        let values = vec![vec![100, 10, 1000], vec![1, 0]];
        let got = share(500, &values);
        assert_eq!(got, vec![vec![400, 40, 500], vec![4, 0]]);
        // Nothing fits a budget of 2 but the empty store.
        assert_eq!(share(2, &values), vec![vec![2, 2, 2], vec![2, 0]]);
    }
}
