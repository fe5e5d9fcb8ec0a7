//! The minijinja templates embedded in the binary (`templates/` of the repository), by the name
//! of what they render: a leaf, so that `plan` bounds the generated files' sizes from the same
//! text that `render` renders.

/// `(name, template)` for each name: the text of `templates/<name>.j2`.
macro_rules! embedded {
    ($($name:literal),* $(,)?) => {
        &[$(($name, include_str!(concat!("../templates/", $name, ".j2")))),*]
    };
}

/// Every generated file's template, by the name of the file it renders.
pub const FILES: &[(&str, &str)] = embedded![
    "loader.py",
    "validate.py",
    "smoke_train.py",
    "policy.py",
    "rollout.py",
    "README.md",
    "dp_normalizer.py",
    "groot_config.py",
];

/// The parts that generated files' templates include, by the name they are included as
/// (`loader/<part>.py`, `validate/<part>.py`: the parts of `loader.py` and `validate.py`, see
/// `render::parts`).
pub const PARTS: &[(&str, &str)] = embedded![
    "loader/dataset.py",
    "loader/dataset_mixture.py",
    "loader/dataset_transforms.py",
    "loader/frames.py",
    "loader/hdf5.py",
    "loader/jpeg.py",
    "loader/mixture.py",
    "loader/mp4.py",
    "loader/parquet.py",
    "loader/png.py",
    "loader/rotations.py",
    "loader/stored_frames.py",
    "loader/transforms.py",
    "loader/video.py",
    "loader/workers.py",
    "loader/zarr.py",
    "validate/cameras_gif.py",
    "validate/cameras_workspace.py",
    "validate/mixture_sampler.py",
    "validate/mixture_stats.py",
    "validate/video_streams.py",
];

/// The embedded template of generated file `name`.
pub fn file(name: &str) -> Option<&'static str> {
    FILES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The parts the template of generated file `name` may include (`<stem>/…`), embedded.
pub fn parts_of(name: &str) -> impl Iterator<Item = &'static (&'static str, &'static str)> + '_ {
    let stem = name.trim_end_matches(".py");
    PARTS.iter().filter(move |(part, _)| {
        part.strip_prefix(stem)
            .is_some_and(|rest| rest.starts_with('/'))
    })
}
