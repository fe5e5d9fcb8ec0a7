//! What a key a source offers is for ([`Role`]), and how the spec maps it ([`KeyRole`]): the
//! rows `chunkc inspect` lists, which [`super::roles`] fills and [`super::state`] completes.

use serde::Serialize;

/// What a key holds, as `chunkc inspect` lists it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Action,
    State,
    /// A camera: frames in the source (`image`) or in video files (`video`).
    Image,
    Video,
    PointCloud,
    /// Another low-dimensional observation (mapped).
    Observation,
    /// Low-dimensional, but not under an observation group: listed, commented out in the spec.
    Unmapped,
    /// Indices, timestamps, rewards, episode markers: never a channel.
    Bookkeeping,
    /// A shape chunkc cannot read as a channel.
    Unusable,
}

impl Role {
    pub fn word(self) -> &'static str {
        match self {
            Role::Action => "action",
            Role::State => "state",
            Role::Image => "image",
            Role::Video => "video",
            Role::PointCloud => "point cloud",
            Role::Observation => "observation",
            Role::Unmapped => "low-dim",
            Role::Bookkeeping => "bookkeeping",
            Role::Unusable => "unusable",
        }
    }

    pub fn is_camera(self) -> bool {
        matches!(self, Role::Image | Role::Video)
    }
}

/// One key, what it is for, and how the spec maps it.
#[derive(Debug, Clone, Serialize)]
pub struct KeyRole {
    pub key: String,
    pub shape: Vec<usize>,
    pub dtype: String,
    pub role: Role,
    /// The channel name it maps to (`None`: not mapped).
    pub channel: Option<String>,
    /// Not mapped, but offered as a commented line: the channel name that line gives it (what
    /// `inspect` prints, and the spec's `# "name" = "key"`).
    pub suggested: Option<String>,
    /// Only some columns (`[start, end)`), when the key holds more than the channel.
    pub columns: Option<[usize; 2]>,
    /// Why it was mapped or left out, where that was a guess.
    pub note: Option<String>,
}

/// The last path component: `observations/images/top` -> `top`, `observation.images.top` -> `top`.
pub fn leaf(key: &str) -> &str {
    key.rsplit(['/', '.']).next().unwrap_or(key)
}
