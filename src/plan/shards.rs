//! Sharded builds: which episodes each of N shards reads, and the identity of the plan the
//! shards and the merge must share.
//!
//! A shard is a contiguous range of episode positions (in the audited manifest's order), cut so
//! that every shard holds about the same number of steps. The assignment depends only on the
//! episode lengths and N, so every machine that plans the same spec over the same source computes
//! the same one, and `chunkc plan --shards N` shows it before anything runs.

use std::ops::Range;
use std::time::Instant;

use serde::Serialize;

use super::Plan;
use crate::error::Result;
use crate::source::{ChannelKind, Source};

/// `--shard I/N`: shard `index` (from 0) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || {
            format!("`{s}`: expected I/N with 0 <= I < N (e.g. 0/4; Slurm: $SLURM_ARRAY_TASK_ID/N)")
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The episode positions of each of `count` shards, given every episode's length: contiguous,
/// in order, covering every episode once, each shard's first episode the one whose steps start
/// at or past its share `k * total / count`. A shard may be empty when there are fewer episodes
/// than shards.
pub fn assign(lens: &[usize], count: usize) -> Vec<Range<usize>> {
    let total: u128 = lens.iter().map(|&l| l as u128).sum();
    let mut cuts = Vec::with_capacity(count + 1);
    let mut before: u128 = 0; // steps of the episodes before position `e`
    let mut e = 0;
    for k in 0..count {
        // Integer arithmetic: the same cut on every machine.
        let share = total * k as u128 / count as u128;
        while e < lens.len() && before < share {
            before += lens[e] as u128;
            e += 1;
        }
        cuts.push(e);
    }
    cuts.push(lens.len());
    cuts.windows(2).map(|w| w[0]..w[1]).collect()
}

/// The identity of a plan for sharding: BLAKE3 of its JSON without the profiles' freshness (which
/// depends on the outputs present where it was planned, not on what the shards compute). Shards
/// record it; the merge refuses a partial whose plan differs from its own.
pub fn plan_id(plan: &Plan) -> String {
    let mut value = serde_json::to_value(plan).expect("a plan serializes");
    if let Some(profiles) = value.get_mut("profiles").and_then(|p| p.as_array_mut()) {
        for p in profiles {
            if let Some(p) = p.as_object_mut() {
                p.remove("status");
            }
        }
    }
    let text = serde_json::to_string(&value).expect("a plan serializes");
    blake3::hash(text.as_bytes()).to_hex().to_string()
}

/// One shard as `chunkc plan --shards N` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct ShardEstimate {
    pub shard: usize,
    /// Episode positions (audited manifest order), and the first and last source ids.
    pub episodes: [usize; 2],
    pub ids: Option<[u64; 2]>,
    pub steps: usize,
    /// Upper bound of the partial: every channel's decoded bytes at every rate the plan builds.
    pub partial_bytes: u64,
    /// The profiles' output bytes (the plan's estimates) in this shard's share of the steps.
    pub output_bytes: u64,
    /// Steps / the measured read rate (one thread: divide by the worker's cores).
    pub read_seconds: f64,
}

/// The assignment of `count` shards with their sizes, and the read rate it was timed at.
#[derive(Debug, Clone, Serialize)]
pub struct ShardsEstimate {
    pub count: usize,
    /// Source ids of the episodes read to time the source, their steps and the seconds it took.
    pub timed_episodes: Vec<u64>,
    pub timed_steps: usize,
    pub timed_seconds: f64,
    pub shards: Vec<ShardEstimate>,
}

/// The assignment of `count` shards, each shard's size and read time: the source's read rate
/// is measured by reading up to three episodes (first, middle, last) on this machine.
pub fn estimate(plan: &Plan, source: &dyn Source, count: usize) -> Result<ShardsEstimate> {
    let manifest = source.manifest();
    let lens: Vec<usize> = manifest.episodes.iter().map(|e| e.len).collect();
    let total: usize = lens.iter().sum();
    let n = lens.len();
    let mut timed: Vec<usize> = vec![0, n / 2, n.saturating_sub(1)];
    timed.dedup();
    let start = Instant::now();
    for &i in &timed {
        source.read_episode(i)?;
    }
    let timed_seconds = start.elapsed().as_secs_f64();
    let timed_steps: usize = timed.iter().map(|&i| lens[i]).sum();
    let per_step = timed_seconds / timed_steps.max(1) as f64;
    let step_bytes: u64 = manifest
        .channels
        .iter()
        .map(|c| match c.kind {
            ChannelKind::Lowdim => 4 * c.width() as u64,
            ChannelKind::Image => c.width() as u64,
        })
        .sum::<u64>()
        * plan.rates.len().max(1) as u64;
    let output: u64 = plan
        .profiles
        .iter()
        .flat_map(|p| &p.files)
        .map(|f| f.estimated_bytes)
        .sum();
    let shards = assign(&lens, count)
        .into_iter()
        .enumerate()
        .map(|(k, r)| {
            let steps: usize = lens[r.clone()].iter().sum();
            let ids = (!r.is_empty()).then(|| {
                [
                    manifest.episodes[r.start].id,
                    manifest.episodes[r.end - 1].id,
                ]
            });
            ShardEstimate {
                shard: k,
                episodes: [r.start, r.end],
                ids,
                steps,
                partial_bytes: step_bytes * steps as u64,
                output_bytes: (output as u128 * steps as u128 / total.max(1) as u128) as u64,
                read_seconds: per_step * steps as f64,
            }
        })
        .collect();
    Ok(ShardsEstimate {
        count,
        timed_episodes: timed.iter().map(|&i| manifest.episodes[i].id).collect(),
        timed_steps,
        timed_seconds,
        shards,
    })
}

/// The table `chunkc plan --shards N` prints after the plan.
pub fn render_text(e: &ShardsEstimate) -> String {
    use super::text::human_bytes;
    let mut out = format!(
        "\nshards: {} (build each with `chunkc build SPEC --shard I/{} --partials DIR`, then `chunkc merge SPEC --partials DIR`)\n",
        e.count, e.count
    );
    out.push_str("  shard  episodes (ids)          steps    partial     output   read time\n");
    for s in &e.shards {
        let ids = s.ids.map_or("-".to_string(), |[a, b]| format!("{a}..={b}"));
        out.push_str(&format!(
            "  {:>5}  {:<22} {:>7} {:>10} {:>10} {:>10.1} s\n",
            s.shard,
            format!("{}..{} ({ids})", s.episodes[0], s.episodes[1]),
            s.steps,
            human_bytes(s.partial_bytes),
            human_bytes(s.output_bytes),
            s.read_seconds
        ));
    }
    out.push_str(&format!(
        "  estimates: partial = decoded bytes at every rate (an upper bound), output = the plan's estimate in proportion to steps, read time = steps at the rate measured reading episodes {:?} ({} steps in {:.3} s, one thread)\n",
        e.timed_episodes, e.timed_steps, e.timed_seconds
    ));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_tile_the_episodes_in_order() {
        let lens = [5, 1, 9, 3, 3, 8, 2, 2, 7];
        for count in 1..=12 {
            let shards = assign(&lens, count);
            assert_eq!(shards.len(), count);
            assert_eq!(shards[0].start, 0);
            assert_eq!(shards[count - 1].end, lens.len());
            for w in shards.windows(2) {
                assert_eq!(w[0].end, w[1].start, "{shards:?}");
            }
        }
    }

    #[test]
    fn equal_episodes_split_evenly() {
        let shards = assign(&[10; 12], 4);
        assert_eq!(shards, vec![0..3, 3..6, 6..9, 9..12]);
        let shards = assign(&[10; 3], 7);
        assert_eq!(shards.iter().filter(|r| !r.is_empty()).count(), 3);
    }

    #[test]
    fn shard_parses_and_rejects() {
        assert_eq!("2/7".parse::<Shard>(), Ok(Shard { index: 2, count: 7 }));
        for bad in ["7/7", "1", "a/2", "0/0", "-1/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
