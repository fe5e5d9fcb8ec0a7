//! The LeRobot export's tasks: each distinct task once, numbered in stored order, and
//! `meta/tasks.parquet` as LeRobot writes it.

use std::sync::Arc;

use arrow_array::RecordBatch;
use arrow_schema::{DataType, Field, Schema};
use serde_json::json;

use super::lerobot_columns::{err, i64_col, CREATED_BY};
use crate::error::Result;

/// The task of an episode without one of its own.
pub(super) const TASK: &str = "chunkc";

/// The export's tasks: each distinct task once, numbered in the order of the first stored
/// episode that has it, and each stored episode's number.
pub(super) struct Tasks {
    pub names: Vec<String>,
    pub of_episode: Vec<usize>,
}

impl Tasks {
    /// Episodes without a task of their own get [`TASK`] (LeRobot needs one for every frame).
    pub(super) fn of(ids: &[u64], tasks: &std::collections::BTreeMap<u64, String>) -> Tasks {
        // Looked up by string: OXE sets have tens of thousands of distinct instructions.
        let mut numbers: std::collections::HashMap<&str, usize> = Default::default();
        let mut names: Vec<String> = Vec::new();
        let of_episode = ids
            .iter()
            .map(|id| {
                let task = tasks.get(id).map_or(TASK, String::as_str);
                *numbers.entry(task).or_insert_with(|| {
                    names.push(task.to_string());
                    names.len() - 1
                })
            })
            .collect();
        if names.is_empty() {
            names.push(TASK.to_string());
        }
        Tasks { names, of_episode }
    }
}

/// `meta/tasks.parquet` as LeRobot writes it (`pandas.DataFrame.to_parquet` of a frame whose
/// index is the task strings): `task_index`, then the strings in `__index_level_0__`, with
/// the `pandas` schema metadata that makes `pd.read_parquet` give them back as the index.
pub fn tasks_table(names: &[String]) -> Result<(Arc<Schema>, RecordBatch)> {
    const INDEX: &str = "__index_level_0__";
    let pandas = json!({
        "index_columns": [INDEX],
        "column_indexes": [{"name": null, "field_name": null, "pandas_type": "unicode",
                            "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": null},
            {"name": null, "field_name": INDEX, "pandas_type": "unicode",
             "numpy_type": "object", "metadata": null},
        ],
        "attributes": {},
        "creator": {"library": CREATED_BY, "version": env!("CARGO_PKG_VERSION")},
    });
    let metadata = [("pandas".to_string(), pandas.to_string())].into();
    let schema = Arc::new(Schema::new_with_metadata(
        vec![
            Field::new("task_index", DataType::Int64, false),
            Field::new(INDEX, DataType::LargeUtf8, false),
        ],
        metadata,
    ));
    let batch = RecordBatch::try_new(
        schema.clone(),
        vec![
            i64_col(0..names.len() as i64),
            Arc::new(arrow_array::LargeStringArray::from_iter_values(
                names.iter(),
            )),
        ],
    )
    .map_err(err)?;
    Ok((schema, batch))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tasks_are_numbered_by_first_stored_episode_and_default_to_chunkc() {
        let tasks = [(7u64, "stack".to_string()), (3, "pick".to_string())].into();
        let t = Tasks::of(&[7, 5, 3, 9, 7], &tasks);
        assert_eq!(t.names, ["stack", TASK, "pick"]);
        assert_eq!(t.of_episode, [0, 1, 2, 1, 0]);
        let none = Tasks::of(&[], &Default::default());
        assert_eq!(none.names, [TASK]);
    }
}
