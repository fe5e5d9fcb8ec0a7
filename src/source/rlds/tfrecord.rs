//! TFRecord framing, read without TensorFlow.
//!
//! A TFRecord file is a run of records, each
//! `u64 length (LE) | u32 masked crc32c(length) | data | u32 masked crc32c(data)`, where
//! `mask(c) = ((c >> 15) | (c << 17)) + 0xa282ead8`. Both checksums are verified: a flipped
//! byte in a shard is an error naming the shard, the record and its byte offset, never a
//! silently wrong frame. Records are found with a sequential scan ([`scan`]) and read back one
//! at a time by offset ([`read_at`]), so that no more than one record is in memory per reader.

use std::fs::File;
use std::io::{BufReader, Read};
use std::os::unix::fs::FileExt;
use std::path::Path;

use crate::error::{Error, Result};

/// crc32c (Castagnoli, reflected polynomial 0x82F63B78), slicing by 8.
fn tables() -> &'static [[u32; 256]; 8] {
    static TABLES: std::sync::OnceLock<[[u32; 256]; 8]> = std::sync::OnceLock::new();
    TABLES.get_or_init(|| {
        let mut t = [[0u32; 256]; 8];
        for i in 0..256u32 {
            let mut c = i;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    (c >> 1) ^ 0x82F6_3B78
                } else {
                    c >> 1
                };
            }
            t[0][i as usize] = c;
        }
        for i in 0..256 {
            for k in 1..8 {
                let prev = t[k - 1][i];
                t[k][i] = (prev >> 8) ^ t[0][(prev & 0xff) as usize];
            }
        }
        t
    })
}

/// The crc32c of `data`.
pub fn crc32c(data: &[u8]) -> u32 {
    let t = tables();
    let mut crc = !0u32;
    let mut chunks = data.chunks_exact(8);
    for c in &mut chunks {
        let lo = u32::from_le_bytes([c[0], c[1], c[2], c[3]]) ^ crc;
        let hi = u32::from_le_bytes([c[4], c[5], c[6], c[7]]);
        crc = t[7][(lo & 0xff) as usize]
            ^ t[6][((lo >> 8) & 0xff) as usize]
            ^ t[5][((lo >> 16) & 0xff) as usize]
            ^ t[4][(lo >> 24) as usize]
            ^ t[3][(hi & 0xff) as usize]
            ^ t[2][((hi >> 8) & 0xff) as usize]
            ^ t[1][((hi >> 16) & 0xff) as usize]
            ^ t[0][(hi >> 24) as usize];
    }
    for &b in chunks.remainder() {
        crc = (crc >> 8) ^ t[0][((crc ^ u32::from(b)) & 0xff) as usize];
    }
    !crc
}

/// TFRecord's masked crc32c.
pub fn masked_crc(data: &[u8]) -> u32 {
    let c = crc32c(data);
    c.rotate_right(15).wrapping_add(0xa282_ead8)
}

/// Where one record's data lies in its shard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record {
    /// Byte offset of the record's header (its length field) in the shard.
    pub offset: u64,
    /// Length of the data.
    pub len: u64,
}

/// Bytes of framing before a record's data, and after it.
const HEADER: u64 = 12;
const FOOTER: u64 = 4;

fn check_header(header: &[u8; 12], shard: &str, index: usize, offset: u64) -> Result<u64> {
    let len = u64::from_le_bytes(header[..8].try_into().expect("8 bytes"));
    let stored = u32::from_le_bytes(header[8..].try_into().expect("4 bytes"));
    let computed = masked_crc(&header[..8]);
    if stored != computed {
        return Err(Error::source(format!(
            "{shard}: record {index} at byte offset {offset}: length checksum mismatch (stored {stored:#010x}, computed {computed:#010x}); the shard is corrupt"
        )));
    }
    Ok(len)
}

fn check_data(data: &[u8], stored: u32, shard: &str, index: usize, offset: u64) -> Result<()> {
    let computed = masked_crc(data);
    if stored != computed {
        return Err(Error::source(format!(
            "{shard}: record {index} at byte offset {offset}: data checksum mismatch (stored {stored:#010x}, computed {computed:#010x}); the shard is corrupt"
        )));
    }
    Ok(())
}

fn truncated(shard: &str, index: usize, offset: u64, need: u64, size: u64) -> Error {
    Error::source(format!(
        "{shard}: truncated: record {index} at byte offset {offset} needs {need} bytes, but the file ends after {}",
        size.saturating_sub(offset)
    ))
}

/// Reads every record of the shard at `path` in order (`shown` names it in messages), checking
/// both checksums, and calls `each(index, record, data)` with each one's data. One record is
/// in memory at a time.
pub fn scan(
    path: &Path,
    shown: &str,
    mut each: impl FnMut(usize, Record, &[u8]) -> Result<()>,
) -> Result<Vec<Record>> {
    let file = File::open(path).map_err(|e| Error::source(format!("{shown}: cannot open: {e}")))?;
    let size = file
        .metadata()
        .map_err(|e| Error::source(format!("{shown}: cannot stat: {e}")))?
        .len();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut records = Vec::new();
    let mut offset = 0u64;
    let mut data = Vec::new();
    while offset < size {
        let index = records.len();
        if size - offset < HEADER {
            return Err(truncated(shown, index, offset, HEADER, size));
        }
        let mut header = [0u8; 12];
        reader
            .read_exact(&mut header)
            .map_err(|e| Error::source(format!("{shown}: cannot read: {e}")))?;
        let len = check_header(&header, shown, index, offset)?;
        let need = HEADER.saturating_add(len).saturating_add(FOOTER);
        if size - offset < need {
            return Err(truncated(shown, index, offset, need, size));
        }
        data.resize(len as usize, 0);
        let mut crc = [0u8; 4];
        reader
            .read_exact(&mut data)
            .and_then(|_| reader.read_exact(&mut crc))
            .map_err(|e| Error::source(format!("{shown}: cannot read: {e}")))?;
        check_data(&data, u32::from_le_bytes(crc), shown, index, offset)?;
        let record = Record { offset, len };
        each(index, record, &data)?;
        records.push(record);
        offset += need;
    }
    Ok(records)
}

/// Reads the record `index` at `record` of an open shard again, checking both checksums.
pub fn read_at(file: &File, record: Record, shown: &str, index: usize) -> Result<Vec<u8>> {
    let mut buf = vec![0u8; (HEADER + record.len + FOOTER) as usize];
    file.read_exact_at(&mut buf, record.offset).map_err(|e| {
        Error::source(format!(
            "{shown}: record {index} at byte offset {}: cannot read: {e}",
            record.offset
        ))
    })?;
    let header: [u8; 12] = buf[..12].try_into().expect("12 bytes");
    let len = check_header(&header, shown, index, record.offset)?;
    if len != record.len {
        return Err(Error::source(format!(
            "{shown}: record {index} at byte offset {}: changed while it was read",
            record.offset
        )));
    }
    let end = (HEADER + len) as usize;
    let stored = u32::from_le_bytes(buf[end..end + 4].try_into().expect("4 bytes"));
    check_data(&buf[12..end], stored, shown, index, record.offset)?;
    buf.truncate(end);
    buf.drain(..12);
    Ok(buf)
}

/// Frames `data` as one TFRecord record (for `chunkc synth` and tests).
pub fn frame(data: &[u8], out: &mut Vec<u8>) {
    let len = (data.len() as u64).to_le_bytes();
    out.extend_from_slice(&len);
    out.extend_from_slice(&masked_crc(&len).to_le_bytes());
    out.extend_from_slice(data);
    out.extend_from_slice(&masked_crc(data).to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32c_known_values() {
        // RFC 3720 B.4 test vectors.
        assert_eq!(crc32c(&[0u8; 32]), 0x8A91_36AA);
        assert_eq!(crc32c(&[0xffu8; 32]), 0x62A8_AB43);
        let inc: Vec<u8> = (0..32).collect();
        assert_eq!(crc32c(&inc), 0x46DD_794E);
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
    }

    #[test]
    fn frames_and_scans_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.tfrecord");
        let mut bytes = Vec::new();
        frame(b"hello", &mut bytes);
        frame(b"", &mut bytes);
        frame(&[7u8; 1000], &mut bytes);
        std::fs::write(&path, &bytes).unwrap();
        let mut seen = Vec::new();
        let records = scan(&path, "x", |_, _, d| {
            seen.push(d.to_vec());
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, vec![b"hello".to_vec(), vec![], vec![7u8; 1000]]);
        let file = File::open(&path).unwrap();
        assert_eq!(read_at(&file, records[2], "x", 2).unwrap(), vec![7u8; 1000]);

        let mut bad = bytes.clone();
        bad[12 + 5 + 4 + 3] ^= 1; // the second record's length
        std::fs::write(&path, &bad).unwrap();
        let err = scan(&path, "x", |_, _, _| Ok(())).unwrap_err().to_string();
        assert!(
            err.contains("record 1 at byte offset 21") && err.contains("checksum"),
            "{err}"
        );
        std::fs::write(&path, &bytes[..bytes.len() - 2]).unwrap();
        let err = scan(&path, "x", |_, _, _| Ok(())).unwrap_err().to_string();
        assert!(err.contains("truncated: record 2"), "{err}");
    }
}
