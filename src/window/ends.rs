//! Episode boundaries in a stored array: the exclusive cumulative ends every layout writes
//! (`meta/episode_ends`), and the row range of each episode they imply. One type, so that "the
//! first episode starts at row 0" is written once; encoded frames packed back to back in a byte
//! buffer use the same rule ([`Ends`] is the general name).

use std::ops::{Deref, Range};

/// Exclusive ends of pieces stored one after another: piece `e` holds rows `ends[e-1]..ends[e]`
/// (from row 0 for the first).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Ends(Vec<u64>);

/// The ends of the episodes in a profile's per-step arrays.
pub type EpisodeEnds = Ends;

impl Ends {
    pub fn new(ends: Vec<u64>) -> Ends {
        debug_assert!(ends.windows(2).all(|w| w[0] <= w[1]), "ends not sorted");
        Ends(ends)
    }

    /// Appends an episode of `len` rows.
    pub fn push(&mut self, len: usize) {
        let end = self.total() as u64 + len as u64;
        self.0.push(end);
    }

    /// The first row of episode `e`.
    pub fn start(&self, e: usize) -> usize {
        self.rows(e..e).start
    }

    /// The rows of episode `e`.
    pub fn range(&self, e: usize) -> Range<usize> {
        self.rows(e..e + 1)
    }

    /// Steps of episode `e`.
    pub fn len_of(&self, e: usize) -> usize {
        self.range(e).len()
    }

    /// The rows of episodes `lo..hi` together (empty at `lo` when `lo == hi`).
    pub fn rows(&self, episodes: Range<usize>) -> Range<usize> {
        let end_of = |e: usize| if e == 0 { 0 } else { self.0[e - 1] as usize };
        end_of(episodes.start)..end_of(episodes.end)
    }

    /// Rows of all episodes.
    pub fn total(&self) -> usize {
        self.0.last().map_or(0, |&e| e as usize)
    }
}

impl Deref for Ends {
    type Target = [u64];

    fn deref(&self) -> &[u64] {
        &self.0
    }
}

impl From<&[u64]> for Ends {
    fn from(ends: &[u64]) -> Ends {
        Ends::new(ends.to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::EpisodeEnds;

    #[test]
    fn ranges_tile_the_rows() {
        let mut ends = EpisodeEnds::default();
        for len in [3, 1, 4] {
            ends.push(len);
        }
        assert_eq!(&ends[..], &[3, 4, 8]);
        assert_eq!(ends.range(0), 0..3);
        assert_eq!(ends.range(2), 4..8);
        assert_eq!(ends.len_of(1), 1);
        assert_eq!(ends.rows(1..3), 3..8);
        assert_eq!(ends.rows(2..2), 4..4);
        assert_eq!(ends.start(0), 0);
        assert_eq!(ends.total(), 8);
        assert_eq!(EpisodeEnds::default().total(), 0);
    }
}
