//! The arrow columns of chunkc's LeRobot export: how a low-dim feature of any shape, a PNG image
//! and an integer column are laid out, and which cameras can be stored as video.

use std::sync::Arc;

use arrow_array::{Array, ArrayRef, FixedSizeListArray, Float32Array, Int64Array};
use arrow_schema::{DataType, Field, Fields};

use super::video_encode::StreamShape;
use crate::error::{Error, Result};
use crate::source::ChannelKind;

/// A channel as the LeRobot exports see it: its name, per-step shape and kind.
pub(super) type Channel = (String, Vec<usize>, ChannelKind);

/// The `created_by` of every parquet file chunkc writes.
pub(super) const CREATED_BY: &str = "chunkc";

pub(super) fn err(e: impl std::fmt::Display) -> Error {
    Error::output(format!("parquet: {e}"))
}

pub(super) fn image_fields() -> Fields {
    Fields::from(vec![
        Field::new("bytes", DataType::Binary, true),
        Field::new("path", DataType::Utf8, true),
    ])
}

pub(super) fn item() -> Arc<Field> {
    Arc::new(Field::new("item", DataType::Float32, true))
}

/// The per-step shape's axes as list levels: LeRobot stores a `(a, b)` feature as a list of `a`
/// lists of `b` values, so each axis is one level of fixed-size list, and a one-value feature
/// (`shape: [1]` in info.json, or a scalar) as a plain `float32` column: its `datasets`
/// features make `(1,)` a `Value`, and `LeRobotDataset` cannot cast a one-item list to it.
pub(super) fn axes(shape: &[usize]) -> Vec<i32> {
    match shape {
        [] | [1] => Vec::new(),
        _ => shape.iter().map(|&d| d as i32).collect(),
    }
}

/// The arrow type of a low-dim feature of `shape`: fixed-size lists nested once per axis.
pub(super) fn lowdim_type(shape: &[usize]) -> DataType {
    let mut field = item();
    let mut dt = DataType::Float32;
    for &d in axes(shape).iter().rev() {
        dt = DataType::FixedSizeList(field, d);
        field = Arc::new(Field::new("item", dt.clone(), true));
    }
    dt
}

/// Rows of `shape` (row-major `values`) as the nested fixed-size lists of [`lowdim_type`].
pub(super) fn lowdim_column(values: Vec<f32>, shape: &[usize]) -> Result<ArrayRef> {
    let mut array: ArrayRef = Arc::new(Float32Array::from(values));
    let mut field = item();
    for &d in axes(shape).iter().rev() {
        let list = FixedSizeListArray::try_new(field, d, array, None).map_err(err)?;
        field = Arc::new(Field::new("item", list.data_type().clone(), true));
        array = Arc::new(list);
    }
    Ok(array)
}

pub(super) fn i64_col(values: impl IntoIterator<Item = i64>) -> ArrayRef {
    Arc::new(Int64Array::from_iter_values(values))
}

/// The stream of camera `name` of per-step `shape`: RGB frames only (LeRobot's videos are
/// three-channel); any other camera is an error that says to keep it PNG.
pub(super) fn video_shape(name: &str, shape: &[usize], fps: f64) -> Result<StreamShape> {
    match shape {
        [height, width, 3] => Ok(StreamShape {
            height: *height,
            width: *width,
            fps,
        }),
        _ => Err(Error::output(format!(
            "channel `{name}`: `image_encoding = \"video\"` stores (height, width, 3) RGB frames, \
             and this channel's frames are {shape:?}; use `image_encoding = \"png\"`"
        ))),
    }
}
