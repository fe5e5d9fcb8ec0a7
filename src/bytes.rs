//! `f32` values seen as the little-endian bytes chunkc reads and writes, without a copy.
//!
//! Low-dim values move between memory and files (the source's contiguous datasets, a store's
//! spilled columns, the output's chunks) as little-endian `f32`. On a little-endian machine that
//! is the values' own memory, so reads land in the `f32` buffer itself and writes send it as it
//! is; on a big-endian one the bytes are swapped in place after a read.

/// The bytes of `values`, as they are in memory.
pub fn f32_bytes(values: &[f32]) -> &[u8] {
    // SAFETY: any initialized `f32` is 4 initialized bytes, u8 has alignment 1, and the slice
    // borrows `values` for its whole life.
    unsafe {
        std::slice::from_raw_parts(values.as_ptr().cast::<u8>(), std::mem::size_of_val(values))
    }
}

/// The bytes of `values`, to be filled with little-endian `f32`s; call [`from_le`] after.
pub fn f32_bytes_mut(values: &mut [f32]) -> &mut [u8] {
    // SAFETY: as in `f32_bytes`, and every bit pattern is a valid `f32`, so whatever is written
    // through the bytes leaves valid values; the borrow is exclusive.
    unsafe {
        std::slice::from_raw_parts_mut(
            values.as_mut_ptr().cast::<u8>(),
            std::mem::size_of_val(values),
        )
    }
}

/// Turns values whose bytes were filled with little-endian `f32`s into this machine's `f32`s
/// (nothing to do on a little-endian machine).
pub fn from_le(values: &mut [f32]) {
    if cfg!(target_endian = "big") {
        for v in values {
            *v = f32::from_bits(u32::from_le(v.to_bits()));
        }
    }
}

/// Reads `values.len()` little-endian `f32`s at `offset` of `file` into `values`.
pub fn read_f32_at(file: &std::fs::File, values: &mut [f32], offset: u64) -> std::io::Result<()> {
    use std::os::unix::fs::FileExt;
    file.read_exact_at(f32_bytes_mut(values), offset)?;
    from_le(values);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_are_little_endian_f32() {
        let values = [1.5f32, -0.0, f32::MAX, 3.25e-7];
        let expected: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        if cfg!(target_endian = "little") {
            assert_eq!(f32_bytes(&values), expected.as_slice());
        }
        let mut back = [0f32; 4];
        f32_bytes_mut(&mut back).copy_from_slice(&expected);
        from_le(&mut back);
        assert_eq!(back.map(f32::to_bits), values.map(f32::to_bits));
    }

    #[test]
    fn reads_f32_from_a_file_offset() {
        use std::io::Write;
        let mut file = tempfile::tempfile().unwrap();
        let values: Vec<f32> = (0..100).map(|i| i as f32 * 0.5 - 7.0).collect();
        file.write_all(&[9, 9, 9]).unwrap();
        for v in &values {
            file.write_all(&v.to_le_bytes()).unwrap();
        }
        let mut got = vec![0f32; 40];
        read_f32_at(&file, &mut got, 3 + 4 * 10).unwrap();
        assert_eq!(got, &values[10..50]);
        assert!(
            read_f32_at(&file, &mut [0f32; 2], 3 + 4 * 99).is_err(),
            "past the end"
        );
    }
}
