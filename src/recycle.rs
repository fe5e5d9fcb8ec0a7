//! Large byte buffers handed back after use, so that the next episode's frames land in memory
//! that is already mapped.
//!
//! An episode of camera frames is hundreds of megabytes (300 rows × two 640×480 cameras:
//! 553 MB). A fresh buffer of that size is a fresh mapping: the kernel faults in and zeroes each
//! page as the decoder first writes it, and unmaps it all when the episode is dropped. Measured
//! with `perf` on a LeRobot AV1 build (`bench/video_read.py`), that zeroing and faulting was a
//! quarter of the build's time, more than the AV1 decoder's own share. The pass hands each
//! episode's uncompressed frames back here once the sinks have written them, and the source
//! takes them for the next episode's decode.
//!
//! A buffer from [`take`] holds whatever its last user left in it: the caller must overwrite
//! every byte before anything reads it (the video decoder does: every row gets its frame, or the
//! episode fails and the buffer comes back unread), so the output bytes never depend on which
//! buffer was reused. A pool keeps at most [`MAX_BUFFERS_PER_THREAD`] buffers per thread, only
//! those of at least [`MIN_BYTES`], and [`clear`] frees them when a pass ends, so memory stays
//! bounded by what a batch of episodes held at once.

use std::sync::Mutex;

/// Buffers smaller than this are not worth keeping (an allocator reuses them by itself).
pub const MIN_BYTES: usize = 4 << 20;

/// The most buffers kept at once, per thread of the pool: a batch of camera episodes is one per
/// thread ([`crate::exec`]), so more would only hold memory no decode will ask for (64 kept
/// buffers of 400 MB grew a 43-episode 640x480 build to 7.9 GB).
pub const MAX_BUFFERS_PER_THREAD: usize = 1;

/// Kept buffers; the process has one ([`take`], [`give`], [`clear`]).
pub struct Pool(Mutex<Vec<Vec<u8>>>);

static POOL: Pool = Pool::new();

impl Pool {
    pub const fn new() -> Pool {
        Pool(Mutex::new(Vec::new()))
    }

    fn kept(&self) -> std::sync::MutexGuard<'_, Vec<Vec<u8>>> {
        // A panic while the lock was held left a list of plain buffers: still usable.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A buffer of `len` bytes whose contents are unspecified (a previous user's bytes, or
    /// zeros): the caller overwrites all of them. The kept buffer that fits `len` most tightly,
    /// else the largest kept one grown to `len`, else a new one.
    pub fn take(&self, len: usize) -> Vec<u8> {
        let reused = {
            let mut kept = self.kept();
            let fits = (0..kept.len())
                .filter(|&i| kept[i].capacity() >= len)
                .min_by_key(|&i| kept[i].capacity());
            let pick = fits.or_else(|| (0..kept.len()).max_by_key(|&i| kept[i].capacity()));
            pick.map(|i| kept.swap_remove(i))
        };
        match reused {
            Some(mut buf) => {
                // Exactly: a doubled capacity would be memory no episode asked for.
                buf.reserve_exact(len.saturating_sub(buf.len()));
                buf.resize(len, 0);
                buf
            }
            None => vec![0u8; len],
        }
    }

    /// Keeps a buffer for a later [`Pool::take`] (drops it instead when it is small or the
    /// pool full).
    pub fn give(&self, buf: Vec<u8>) {
        if buf.capacity() < MIN_BYTES {
            return;
        }
        let mut kept = self.kept();
        if kept.len() < MAX_BUFFERS_PER_THREAD * rayon::current_num_threads().max(1) {
            kept.push(buf);
        }
    }

    /// Frees every kept buffer.
    pub fn clear(&self) {
        let freed = std::mem::take(&mut *self.kept());
        drop(freed);
    }

    /// How many buffers are kept.
    pub fn len(&self) -> usize {
        self.kept().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl Default for Pool {
    fn default() -> Pool {
        Pool::new()
    }
}

/// [`Pool::take`] from the process's pool.
pub fn take(len: usize) -> Vec<u8> {
    POOL.take(len)
}

/// [`Pool::give`] to the process's pool.
pub fn give(buf: Vec<u8>) {
    POOL.give(buf)
}

/// Frees the process's kept buffers (the end of a pass).
pub fn clear() {
    POOL.clear()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_come_back_with_the_length_asked_for() {
        let pool = Pool::new();
        let mut a = pool.take(MIN_BYTES);
        assert_eq!(a.len(), MIN_BYTES);
        a.fill(7);
        let ptr = a.as_ptr();
        pool.give(a);
        // The same memory, shorter: its bytes are the old ones (the caller overwrites them).
        let b = pool.take(MIN_BYTES / 2);
        assert_eq!((b.as_ptr(), b.len()), (ptr, MIN_BYTES / 2));
        assert!(b.iter().all(|&v| v == 7));
        pool.give(b);
        // Longer than any kept buffer: the largest grows, its new tail zeroed.
        let c = pool.take(MIN_BYTES + 10);
        assert_eq!(c.len(), MIN_BYTES + 10);
        assert!(c[MIN_BYTES..].iter().all(|&v| v == 0));
        assert!(pool.is_empty());
        // Small buffers are not kept; the tightest fit is taken.
        pool.give(vec![1u8; 16]);
        pool.give(c);
        pool.give(vec![2u8; 2 * MIN_BYTES]);
        assert_eq!(pool.len(), 2);
        assert_eq!(pool.take(MIN_BYTES).capacity(), MIN_BYTES + 10);
        pool.clear();
        assert!(pool.is_empty());
    }
}
