//! Stage 1, parse: TOML → typed [`Spec`] → fully explicit [`Profile`]s.
//!
//! - `model`: the serde/schemars types as written (no engine dependencies).
//! - `load`: [`LoadedSpec`], the typed spec with its expanded profiles and the spanned TOML
//!   document, so that any stage can point at a key (`file:line:col`).
//! - `parse`: reads the file (TOML → document → [`Spec`] → validated profiles); `serde_error`
//!   turns serde's errors into diagnostics that name the key and say "did you mean".
//! - `validate`: semantic checks that need no source (ranges, channel names, references).
//! - `preset`: preset expansion into [`Profile`] (`profile`), over each preset's table of values
//!   (`preset_values`).
//! - `video_settings`: the encoder settings of a profile that stores frames as video, and their
//!   defaults.
//! - `image_storage`: how the HDF5 layout stores frames (`image_compression`) and its defaults.
//! - `export_keys`: the names native exports give their arrays (default rule and overrides).
//! - `modality`: GR00T's parts of each channel (`[profiles.<name>.modality]`), the tiling they
//!   must make, and the name of a channel's one part when none are given.
//! - `camera`: `[profiles.<name>.cameras.<channel>]`, a camera's stored size, as written and
//!   resolved; `validate_camera` checks it (the checks against the source's frames are the
//!   plan's).
//! - `transform`: `[[profiles.<name>.transforms]]` and `stats_population` as written (the
//!   rotation kinds are the `rotation` leaf's).
//! - `diagnostic`: renders an error with the offending text underlined.
//! - `observations`: the warning for a profile whose preset needs observations in a spec that
//!   maps none (`chunkc check`).
//! - `output_location`: where the outputs may go (never into the source; through a symlink
//!   only when the spec allows it).
//! - `reference`: the spec's documentation read from the JSON Schema (book chapter, hints).

mod camera;
mod diagnostic;
pub mod env;
pub mod export_keys;
mod image_storage;
mod load;
mod memory;
pub mod modality;
pub mod model;
mod observations;
mod output_location;
mod parse;
mod preset;
mod preset_values;
mod profile;
pub mod reference;
mod serde_error;
mod transform;
mod validate;
mod validate_camera;
mod video_settings;

pub use camera::{Camera, CameraSpec};
pub(crate) use diagnostic::suggest as suggest_name;
pub use diagnostic::Diagnostic;
pub use image_storage::DEFAULT_IMAGE_QUALITY;
pub(crate) use load::dotted as dotted_key;
pub use load::{LoadedSpec, SourceView};
pub use model::*;
pub use observations::missing_observations;
pub use output_location::check_output_location;
pub use profile::Profile;
pub use transform::{DeltaSpec, Layout6d, RelativePoseSpec, RotationKind, RotationSpec};
pub use video_settings::{
    StreamCopy, VideoSettings, DEFAULT_VIDEO_CRF, DEFAULT_VIDEO_GOP, HAS_X264, STORAGE_VIDEO,
};

/// The JSON Schema of the spec, pretty-printed with a trailing newline (`chunkc schema`).
pub fn json_schema() -> String {
    let schema = schemars::schema_for!(Spec);
    let mut s = serde_json::to_string_pretty(&schema).expect("schema serializes");
    s.push('\n');
    s
}
