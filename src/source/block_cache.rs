// Long file: one structure: the cache, its decode-once protocol and its budget.
//! Decoded blocks shared by the episodes that overlap them, so that a block is decoded at most
//! once per build whatever the source's chunking.
//!
//! A *block* is one storage chunk of a source file (a zarr or HDF5 chunk, a parquet row group);
//! chunkc keeps the word *chunk* for the action chunk, so "chunk" below means a block.
//!
//! A zarr chunk of 36,000 rows holds 90 episodes of 400 steps; a parquet row group may hold a
//! whole LeRobot v3.0 file. Read one episode at a time, such a chunk would be decoded once per
//! episode (90× the work). The adapters know, when they open a source, every episode's row
//! range, hence how many episode reads will take rows from each chunk (its *users*). A chunk is
//! decoded by the first reader that needs it and kept until its last user has taken its rows,
//! then dropped at once: the build reads episodes in storage order (in parallel batches), so
//! only the chunks around the batch being read are held.
//!
//! - **Decode once under parallel readers**: a reader that needs a chunk another thread is
//!   decoding waits for it (a condition variable) instead of decoding it again.
//! - **Bounded memory**: the chunks held never exceed a byte budget (`CHUNKC_DECODE_CACHE_MB`,
//!   256 MiB by default). A chunk decoded while the budget is spent is handed to its reader but
//!   not kept, so its other users decode it again: correct, slower, and counted. The chunks
//!   already held are the ones the next episodes need (storage order), so they stay.
//! - **Counted**: every decode of every chunk is counted ([`DecodeCounts`]); the build reports
//!   the counts, and the tests prove each chunk is decoded exactly once.
//!
//! Decodes done outside the cache (an HDF5 dataset that belongs to one episode, read whole) are
//! counted with [`BlockCache::count`].

use std::collections::{BTreeMap, HashMap};
use std::hash::Hash;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::ThreadId;

/// How many times each storage chunk was decoded: per array (or dataset, or parquet column, as
/// the adapter names it), per chunk (its index in the chunk grid; one linear index for HDF5
/// datasets and parquet row groups).
pub type DecodeCounts = BTreeMap<String, BTreeMap<Vec<u64>, u32>>;

/// The default budget for decoded chunks held at once.
pub const DEFAULT_BUDGET: usize = 256 << 20;

/// The budget from `CHUNKC_DECODE_CACHE_MB` (MiB), else [`DEFAULT_BUDGET`].
pub fn budget_from_env() -> usize {
    std::env::var("CHUNKC_DECODE_CACHE_MB")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .map_or(DEFAULT_BUDGET, |mb| mb << 20)
}

enum Slot<V> {
    /// A thread is decoding it; readers wait.
    Decoding(ThreadId),
    /// Decoded, waiting for `remaining` more readers.
    Ready {
        value: Arc<V>,
        bytes: usize,
        remaining: u32,
    },
}

struct State<K, V> {
    slots: HashMap<K, Slot<V>>,
    /// Bytes of the `Ready` slots.
    held: usize,
    /// Decodes per key, over the cache's life.
    decodes: HashMap<K, u32>,
}

/// Decoded chunks keyed by `K`, each kept until its users have taken it (see the module
/// documentation).
pub struct BlockCache<K, V> {
    state: Mutex<State<K, V>>,
    decoded: Condvar,
    budget: usize,
}

impl<K: Hash + Eq + Clone, V> BlockCache<K, V> {
    pub fn new(budget: usize) -> Self {
        BlockCache {
            state: Mutex::new(State {
                slots: HashMap::new(),
                held: 0,
                decodes: HashMap::new(),
            }),
            decoded: Condvar::new(),
            budget,
        }
    }

    fn lock(&self) -> MutexGuard<'_, State<K, V>> {
        // A panic while the lock was held left no slot half-changed (every change is one
        // statement), so a poisoned lock is still consistent.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The chunk `key`, which `users` episode reads take in all (this one included): from the
    /// cache, or decoded by `decode` (which gives the value and its size in bytes). The last of
    /// the `users` readers drops it from the cache.
    pub fn get<E>(
        &self,
        key: &K,
        users: u32,
        decode: impl FnOnce() -> Result<(V, usize), E>,
    ) -> Result<Arc<V>, E> {
        let me = std::thread::current().id();
        let mut state = self.lock();
        loop {
            match state.slots.get_mut(key) {
                Some(Slot::Ready {
                    value, remaining, ..
                }) => {
                    let value = value.clone();
                    *remaining = remaining.saturating_sub(1);
                    if *remaining == 0 {
                        if let Some(Slot::Ready { bytes, .. }) = state.slots.remove(key) {
                            state.held -= bytes;
                        }
                    }
                    return Ok(value);
                }
                // The decoding thread itself asks again (rayon ran another episode's read on it
                // while it waited inside the decode): waiting would never end; decode here too.
                Some(Slot::Decoding(by)) if *by == me => {
                    drop(state);
                    return self.decode_uncached(key, decode);
                }
                Some(Slot::Decoding(_)) => {
                    state = self.decoded.wait(state).unwrap_or_else(|p| p.into_inner());
                }
                None => break,
            }
        }
        state.slots.insert(key.clone(), Slot::Decoding(me));
        *state.decodes.entry(key.clone()).or_insert(0) += 1;
        drop(state);

        // Whatever happens in `decode` (an error, a panic), the slot must not stay `Decoding`,
        // or the readers waiting for it would wait forever.
        struct Clear<'a, K: Hash + Eq + Clone, V> {
            cache: &'a BlockCache<K, V>,
            key: &'a K,
            armed: bool,
        }
        impl<K: Hash + Eq + Clone, V> Drop for Clear<'_, K, V> {
            fn drop(&mut self) {
                if self.armed {
                    self.cache.lock().slots.remove(self.key);
                    self.cache.decoded.notify_all();
                }
            }
        }
        let mut clear = Clear {
            cache: self,
            key,
            armed: true,
        };
        let (value, bytes) = decode()?;
        clear.armed = false;
        let value = Arc::new(value);
        let mut state = self.lock();
        let remaining = users.saturating_sub(1);
        if remaining > 0 && state.held + bytes <= self.budget {
            state.held += bytes;
            state.slots.insert(
                key.clone(),
                Slot::Ready {
                    value: value.clone(),
                    bytes,
                    remaining,
                },
            );
        } else {
            state.slots.remove(key);
        }
        drop(state);
        self.decoded.notify_all();
        Ok(value)
    }

    /// Decodes the chunk `key` ahead of its `users` readers, unless it is held or being decoded
    /// already: a reader then finds it ready. Used to decode the chunks a batch of episodes needs
    /// side by side before the batch is read (several readers of one large chunk would otherwise
    /// wait for the one decoding it). A failed decode is left to the first reader, whose error
    /// names its episode; a chunk over the budget is not kept (and counted when read again).
    pub fn prefill<E>(&self, key: &K, users: u32, decode: impl FnOnce() -> Result<(V, usize), E>) {
        let me = std::thread::current().id();
        {
            let mut state = self.lock();
            if state.slots.contains_key(key) {
                return;
            }
            state.slots.insert(key.clone(), Slot::Decoding(me));
        }
        let decoded = decode();
        let mut state = self.lock();
        match decoded {
            Ok((value, bytes)) if users > 0 && state.held + bytes <= self.budget => {
                *state.decodes.entry(key.clone()).or_insert(0) += 1;
                state.held += bytes;
                state.slots.insert(
                    key.clone(),
                    Slot::Ready {
                        value: Arc::new(value),
                        bytes,
                        remaining: users,
                    },
                );
            }
            Ok(_) => {
                *state.decodes.entry(key.clone()).or_insert(0) += 1;
                state.slots.remove(key);
            }
            Err(_) => {
                state.slots.remove(key);
            }
        }
        drop(state);
        self.decoded.notify_all();
    }

    fn decode_uncached<E>(
        &self,
        key: &K,
        decode: impl FnOnce() -> Result<(V, usize), E>,
    ) -> Result<Arc<V>, E> {
        self.count(key);
        decode().map(|(v, _)| Arc::new(v))
    }

    /// Counts a decode of `key` done outside the cache.
    pub fn count(&self, key: &K) {
        *self.lock().decodes.entry(key.clone()).or_insert(0) += 1;
    }

    /// Bytes of the decoded chunks held now.
    pub fn held_bytes(&self) -> usize {
        self.lock().held
    }

    /// Every key decoded so far, with its number of decodes.
    pub fn decodes(&self) -> Vec<(K, u32)> {
        self.lock()
            .decodes
            .iter()
            .map(|(k, &n)| (k.clone(), n))
            .collect()
    }
}

/// How many of the row ranges `episodes` (sorted, disjoint) overlap each chunk, for chunks that
/// start at rows `chunk_starts` (sorted, the first 0) and together hold `rows` rows: each chunk's
/// users.
pub fn users_per_block(
    episodes: &[std::ops::Range<u64>],
    chunk_starts: &[u64],
    rows: u64,
) -> Vec<u32> {
    let n = chunk_starts.len();
    let mut users = vec![0u32; n];
    for e in episodes
        .iter()
        .filter(|e| e.start < e.end && e.start < rows)
    {
        // The chunk holding the episode's first row, then every chunk starting before its end.
        let first = chunk_starts
            .partition_point(|&s| s <= e.start)
            .saturating_sub(1);
        for (u, _) in users[first..]
            .iter_mut()
            .zip(&chunk_starts[first..])
            .take_while(|(_, &s)| s < e.end)
        {
            *u += 1;
        }
    }
    users
}

/// Decode counts of datasets read whole, keyed by (name, number of chunks): each read of a
/// dataset decodes each of its chunks once.
pub fn whole_datasets(decodes: Vec<((String, u64), u32)>) -> DecodeCounts {
    let mut out = DecodeCounts::new();
    for ((name, chunks), n) in decodes {
        let per = out.entry(name).or_default();
        for i in 0..chunks.max(1) {
            *per.entry(vec![i]).or_insert(0) += n;
        }
    }
    out
}

/// The first rows of chunks of `rows_per_block` rows covering `rows` rows.
pub fn regular_starts(rows_per_block: u64, rows: u64) -> Vec<u64> {
    let k = rows_per_block.max(1);
    (0..rows.div_ceil(k)).map(|i| i * k).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn a_chunk_is_decoded_once_and_dropped_after_its_last_user() {
        let cache: BlockCache<u32, Vec<u8>> = BlockCache::new(1 << 20);
        let calls = AtomicUsize::new(0);
        let decode = || {
            calls.fetch_add(1, Ordering::SeqCst);
            Ok::<_, ()>((vec![7u8; 100], 100))
        };
        for _ in 0..3 {
            assert_eq!(cache.get(&1, 3, decode).unwrap()[0], 7);
        }
        assert_eq!(calls.load(Ordering::SeqCst), 1);
        assert_eq!(cache.held_bytes(), 0);
        // A fourth read (a second pass) decodes it again, and says so.
        cache.get(&1, 3, decode).unwrap();
        assert_eq!(cache.decodes(), vec![(1, 2)]);
    }

    #[test]
    fn parallel_readers_wait_for_the_decoding_one() {
        let cache: Arc<BlockCache<u32, Vec<u8>>> = Arc::new(BlockCache::new(1 << 20));
        let calls = Arc::new(AtomicUsize::new(0));
        let threads: Vec<_> = (0..8)
            .map(|_| {
                let (cache, calls) = (cache.clone(), calls.clone());
                std::thread::spawn(move || {
                    cache
                        .get(&9, 8, || {
                            calls.fetch_add(1, Ordering::SeqCst);
                            std::thread::sleep(std::time::Duration::from_millis(50));
                            Ok::<_, ()>((vec![1u8; 10], 10))
                        })
                        .unwrap()
                        .len()
                })
            })
            .collect();
        for t in threads {
            assert_eq!(t.join().unwrap(), 10);
        }
        assert_eq!(calls.load(Ordering::SeqCst), 1);
        assert_eq!(cache.held_bytes(), 0);
    }

    #[test]
    fn over_the_budget_a_chunk_is_not_kept() {
        let cache: BlockCache<u32, Vec<u8>> = BlockCache::new(150);
        let ok = |n: usize| move || Ok::<_, ()>((vec![0u8; n], n));
        cache.get(&1, 2, ok(100)).unwrap();
        assert_eq!(cache.held_bytes(), 100);
        // Does not fit beside chunk 1: handed out, not kept.
        cache.get(&2, 2, ok(100)).unwrap();
        assert_eq!(cache.held_bytes(), 100);
        cache.get(&2, 2, ok(100)).unwrap();
        cache.get(&1, 2, ok(100)).unwrap();
        let mut d = cache.decodes();
        d.sort();
        assert_eq!(d, vec![(1, 1), (2, 2)]);
        assert_eq!(cache.held_bytes(), 0);
    }

    #[test]
    fn a_failed_decode_leaves_the_chunk_to_the_next_reader() {
        let cache: BlockCache<u32, Vec<u8>> = BlockCache::new(1 << 20);
        assert_eq!(cache.get(&1, 2, || Err("broken")).unwrap_err(), "broken");
        assert_eq!(
            cache.get(&1, 2, || Ok::<_, &str>((vec![1], 1))).unwrap()[0],
            1
        );
    }

    #[test]
    fn a_prefilled_chunk_serves_all_its_readers() {
        let cache: BlockCache<u32, Vec<u8>> = BlockCache::new(1 << 20);
        cache.prefill(&4, 2, || Ok::<_, ()>((vec![5u8; 10], 10)));
        cache.prefill(&4, 2, || -> Result<(Vec<u8>, usize), ()> {
            panic!("decoded twice")
        });
        assert_eq!(cache.held_bytes(), 10);
        let never = || -> Result<(Vec<u8>, usize), ()> { panic!("decoded twice") };
        assert_eq!(cache.get(&4, 2, never).unwrap()[0], 5);
        assert_eq!(cache.get(&4, 2, never).unwrap()[0], 5);
        assert_eq!((cache.held_bytes(), cache.decodes()), (0, vec![(4, 1)]));
        // A failed prefill is not counted; the reader decodes (and would report the error).
        cache.prefill(&6, 1, || Err::<(Vec<u8>, usize), _>("broken"));
        assert!(cache.decodes().iter().all(|(k, _)| *k != 6));
        assert_eq!(
            cache.get(&6, 1, || Ok::<_, ()>((vec![1], 1))).unwrap()[0],
            1
        );
    }

    #[test]
    fn users_are_the_overlapping_episodes() {
        // Episodes of 4, 4 and 2 rows; chunks of 3 rows (the last one partial).
        let eps = [0..4, 4..8, 8..10];
        assert_eq!(
            users_per_block(&eps, &regular_starts(3, 10), 10),
            vec![1, 2, 2, 1]
        );
        assert_eq!(users_per_block(&eps, &regular_starts(100, 10), 10), vec![3]);
        // Row groups of 5 and 5 rows.
        assert_eq!(users_per_block(&eps, &[0, 5], 10), vec![2, 2]);
    }
}
