//! Rows written into an HDF5 dataset through the library, shared by chunkc's HDF5 layouts
//! (`hdf5`, `hdf5_chunks`) and the native HDF5 exports (`hdf5_native`).

use hdf5::Dataset;
use ndarray::{ArrayViewD, IxDyn};

use crate::error::{Error, Result};

/// Writes `values` (whole rows of `ds`, flattened) at rows `lo..` of `ds`, through HDF5.
pub(super) fn write_rows<T: hdf5::H5Type>(ds: &Dataset, lo: usize, values: &[T]) -> Result<()> {
    let shape = ds.shape();
    let rows = values.len() / shape[1..].iter().product::<usize>().max(1);
    let mut dims = shape.clone();
    dims[0] = rows;
    let view = ArrayViewD::from_shape(IxDyn(&dims), values)
        .map_err(|e| Error::Internal(format!("rows of {}: {e}", ds.name())))?;
    let mut sel: Vec<hdf5::SliceOrIndex> = vec![(lo..lo + rows).into()];
    sel.extend(shape[1..].iter().map(|&d| hdf5::SliceOrIndex::from(0..d)));
    ds.write_slice(view, hdf5::Hyperslab::from(sel))?;
    Ok(())
}
