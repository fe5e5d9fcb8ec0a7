//! Where the errors of a profile's transforms point: `profiles.<name>.<key>`, or a field of
//! `transforms[i]`, with the dotted key leading the message.

use crate::error::Error;
use crate::spec::LoadedSpec;

/// Where the errors of one profile's transforms point.
pub(super) struct At<'a> {
    pub spec: &'a LoadedSpec,
    pub profile: &'a str,
}

impl At<'_> {
    pub fn key(&self, path: &[&str], message: String, help: Option<String>) -> Error {
        let mut key = vec!["profiles", self.profile];
        key.extend_from_slice(path);
        self.spec.error_at(&key, message, help)
    }

    /// An error at `transforms[i].<field>`, whose message starts with the dotted key.
    pub fn field(&self, i: usize, field: &str, message: String) -> Error {
        let index = i.to_string();
        self.key(
            &["transforms", &index, field],
            format!(
                "profiles.{}.transforms[{i}].{field}: {message}",
                self.profile
            ),
            None,
        )
    }
}
