//! Per-dimension numbers laid out in a channel's per-step shape.
//!
//! Statistics are computed per dimension of the flattened step (one column per value). Readers
//! of a `(T, a, b)` or `(T, N, 3)` channel index them in its shape, as numpy's `x.mean(axis=0)`
//! does: `stats.json`, `meta.json`'s normalization, LeRobot's `meta/stats.json` (which keeps the
//! feature's shape) and robomimic's `(1, ...)` rows. Diffusion Policy's normalizer, which works on
//! flattened features, keeps the flat vector.

use serde_json::Value;

/// `values` (row-major, one per dimension) as nested JSON arrays of `shape`; a vector (or a
/// scalar) stays flat. Values that do not fill the shape are left flat too.
pub fn nested(values: &[f64], shape: &[usize]) -> Value {
    if shape.len() < 2 || values.len() != shape.iter().product::<usize>() {
        return Value::from(values.to_vec());
    }
    nest(values, shape)
}

fn nest(values: &[f64], shape: &[usize]) -> Value {
    match shape {
        [] | [_] => Value::from(values.to_vec()),
        [first, rest @ ..] => {
            let step = values.len() / (*first).max(1);
            Value::Array(
                (0..*first)
                    .map(|i| nest(&values[i * step..(i + 1) * step], rest))
                    .collect(),
            )
        }
    }
}

/// Every array of numbers directly inside `object` that has one value per dimension, nested in
/// `shape` (other members, such as `count`, are left as they are).
pub fn nest_members(object: &mut Value, shape: &[usize]) {
    let width: usize = shape.iter().product();
    if shape.len() < 2 {
        return;
    }
    if let Value::Object(map) = object {
        for value in map.values_mut() {
            let numbers: Option<Vec<f64>> = value
                .as_array()
                .filter(|a| a.len() == width)
                .and_then(|a| a.iter().map(Value::as_f64).collect());
            if let Some(numbers) = numbers {
                *value = nest(&numbers, shape);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn matrices_nest_row_major_and_vectors_stay_flat() {
        let v: Vec<f64> = (0..6).map(f64::from).collect();
        assert_eq!(
            nested(&v, &[3, 2]),
            json!([[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]])
        );
        assert_eq!(nested(&v, &[6]), json!([0.0, 1.0, 2.0, 3.0, 4.0, 5.0]));
        assert_eq!(
            nested(&v[..4], &[1, 2, 2]),
            json!([[[0.0, 1.0], [2.0, 3.0]]])
        );
        // Not a fill of the shape: left flat rather than guessed.
        assert_eq!(nested(&v[..5], &[3, 2]), json!([0.0, 1.0, 2.0, 3.0, 4.0]));
    }

    #[test]
    fn members_with_one_value_per_dimension_nest() {
        let mut doc = json!({"mean": [1.0, 2.0, 3.0, 4.0], "count": 7, "clip": false});
        nest_members(&mut doc, &[2, 2]);
        assert_eq!(
            doc,
            json!({"mean": [[1.0, 2.0], [3.0, 4.0]], "count": 7, "clip": false})
        );
    }
}
