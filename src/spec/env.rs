//! `profiles.<name>.env`: the simulator a profile's trained policy is rolled out in.
//!
//! Why here: the id is checked when the spec is parsed, so a typo fails `chunkc check` with the
//! key's line instead of failing `rollout.py` after a training run. The form is gymnasium's
//! (`[namespace/]Name-v<version>`); which environments `rollout.py` can drive, and how their
//! observations map onto the profile's channels, is the generated script's business.

/// The environments whose observations `rollout.py` maps onto a profile's channels.
pub const SUPPORTED: &[&str] = &["gym_pusht/PushT-v0"];

/// `Ok` for a well-formed gymnasium id, else the message and a hint.
pub fn check(id: &str) -> Result<(), (String, Option<String>)> {
    let (namespace, name) = match id.split_once('/') {
        Some((ns, name)) => (Some(ns), name),
        None => (None, id),
    };
    let word = |s: &str| {
        !s.is_empty()
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
    };
    let versioned = name.rsplit_once("-v").is_some_and(|(base, v)| {
        word(base) && !v.is_empty() && v.bytes().all(|b| b.is_ascii_digit())
    });
    if namespace.is_none_or(word) && word(name) && versioned {
        return Ok(());
    }
    Err((
        format!("`env` = \"{id}\" is not a gymnasium environment id (`[namespace/]Name-v<N>`)"),
        Some(format!("supported by rollout.py: {}", SUPPORTED.join(", "))),
    ))
}

#[cfg(test)]
mod tests {
    use super::check;

    #[test]
    fn gymnasium_ids() {
        for ok in [
            "gym_pusht/PushT-v0",
            "CartPole-v1",
            "gym_aloha/AlohaInsertion-v0",
        ] {
            assert!(check(ok).is_ok(), "{ok}");
        }
        for bad in [
            "",
            "PushT",
            "gym_pusht/",
            "/PushT-v0",
            "a b/PushT-v0",
            "PushT-vx",
            "a/b/C-v0",
        ] {
            assert!(check(bad).is_err(), "{bad}");
        }
    }
}
