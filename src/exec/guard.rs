//! The one place a per-episode job's panic becomes an error: a bug met on one episode (in an
//! adapter, a repair, an encoder) fails the build with a message naming that episode, instead
//! of unwinding through rayon and aborting with a bare backtrace.

use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::error::{Error, Result};

/// Runs `job` for episode `id`; a panic inside it becomes [`Error::Internal`] naming the episode
/// and the panic's message.
pub(super) fn episode_job<T>(id: u64, job: impl FnOnce() -> Result<T>) -> Result<T> {
    catch_unwind(AssertUnwindSafe(job)).unwrap_or_else(|panic| {
        let what = panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default();
        Err(Error::Internal(format!(
            "panic while processing episode {id}: {what}"
        )))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_names_the_episode_and_an_error_passes_through() {
        let err = episode_job::<()>(7, || panic!("boom {}", 1)).unwrap_err();
        assert!(
            matches!(&err, Error::Internal(m) if m == "panic while processing episode 7: boom 1")
        );
        let err = episode_job::<()>(8, || panic!("static")).unwrap_err();
        assert!(err.to_string().contains("episode 8: static"), "{err}");
        let err = episode_job::<()>(9, || Err(Error::Internal("no".into()))).unwrap_err();
        assert!(matches!(&err, Error::Internal(m) if m == "no"));
        assert_eq!(episode_job(1, || Ok(3)).unwrap(), 3);
    }
}
