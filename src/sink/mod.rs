//! Stage 5b, write: the container writers and the JSON documents beside them.
//!
//! - `hdf5`: chunkc's own `index` layout in HDF5.
//! - `documents`: `meta.json` and `stats.json`.
//! - `dump`: canonical text dumps of written files (golden tests).

pub mod documents;
pub mod dump;
pub mod hdf5;
