//! `tf.train.Example`, decoded by hand (the proto is four small messages; no protobuf runtime).
//!
//! ```text
//! Example  { Features features = 1; }
//! Features { map<string, Feature> feature = 1; }   // entries: key = 1, value = 2
//! Feature  { oneof kind { BytesList bytes_list = 1; FloatList float_list = 2;
//!                         Int64List int64_list = 3; } }
//! BytesList { repeated bytes value = 1; }
//! FloatList { repeated float value = 1 [packed]; }
//! Int64List { repeated int64 value = 1 [packed]; }
//! ```
//!
//! Byte strings are borrowed from the record (an episode's JPEG frames are not copied), numbers
//! are decoded. Packed and unpacked repeated numbers are both accepted, as protobuf requires.
//! Unknown fields are skipped, as protobuf parsers do.

use std::collections::BTreeMap;

/// One feature's values.
#[derive(Debug, Clone, PartialEq)]
pub enum Values<'a> {
    Bytes(Vec<&'a [u8]>),
    Float(Vec<f32>),
    Int64(Vec<i64>),
}

impl Values<'_> {
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn len(&self) -> usize {
        match self {
            Values::Bytes(v) => v.len(),
            Values::Float(v) => v.len(),
            Values::Int64(v) => v.len(),
        }
    }

    /// The list's name in the proto (`float_list`), for messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Values::Bytes(_) => "bytes_list",
            Values::Float(_) => "float_list",
            Values::Int64(_) => "int64_list",
        }
    }
}

/// An Example's features by name.
pub type Example<'a> = BTreeMap<String, Values<'a>>;

struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

type Parse<T> = std::result::Result<T, String>;

impl<'a> Reader<'a> {
    fn new(buf: &'a [u8]) -> Self {
        Reader { buf, at: 0 }
    }

    fn done(&self) -> bool {
        self.at >= self.buf.len()
    }

    fn varint(&mut self) -> Parse<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let Some(&b) = self.buf.get(self.at) else {
                return Err(format!("varint runs past the end at byte {}", self.at));
            };
            self.at += 1;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(format!("varint longer than 10 bytes at byte {}", self.at))
    }

    fn bytes(&mut self) -> Parse<&'a [u8]> {
        let len = self.varint()?;
        let end = usize::try_from(len)
            .ok()
            .and_then(|l| self.at.checked_add(l))
            .filter(|&e| e <= self.buf.len())
            .ok_or_else(|| {
                format!(
                    "a field of {len} bytes runs past the end at byte {}",
                    self.at
                )
            })?;
        let out = &self.buf[self.at..end];
        self.at = end;
        Ok(out)
    }

    fn fixed32(&mut self) -> Parse<u32> {
        let end = self.at + 4;
        let b = self
            .buf
            .get(self.at..end)
            .ok_or_else(|| format!("a fixed32 runs past the end at byte {}", self.at))?;
        self.at = end;
        Ok(u32::from_le_bytes(b.try_into().expect("4 bytes")))
    }

    /// (field number, wire type).
    fn tag(&mut self) -> Parse<(u64, u8)> {
        let t = self.varint()?;
        Ok((t >> 3, (t & 7) as u8))
    }

    fn skip(&mut self, wire: u8) -> Parse<()> {
        match wire {
            0 => self.varint().map(drop),
            1 => {
                self.at = self
                    .at
                    .checked_add(8)
                    .filter(|&e| e <= self.buf.len())
                    .ok_or("a fixed64 runs past the end".to_string())?;
                Ok(())
            }
            2 => self.bytes().map(drop),
            5 => self.fixed32().map(drop),
            w => Err(format!("unsupported wire type {w} at byte {}", self.at)),
        }
    }
}

/// Decodes one serialized `tf.train.Example`.
pub fn parse(buf: &[u8]) -> Parse<Example<'_>> {
    let mut out = Example::new();
    let mut r = Reader::new(buf);
    while !r.done() {
        match r.tag()? {
            (1, 2) => features(r.bytes()?, &mut out)?,
            (_, w) => r.skip(w)?,
        }
    }
    Ok(out)
}

fn features<'a>(buf: &'a [u8], out: &mut Example<'a>) -> Parse<()> {
    let mut r = Reader::new(buf);
    while !r.done() {
        match r.tag()? {
            (1, 2) => {
                let (key, values) = entry(r.bytes()?)?;
                if out.insert(key.clone(), values).is_some() {
                    return Err(format!("feature `{key}` appears twice"));
                }
            }
            (_, w) => r.skip(w)?,
        }
    }
    Ok(())
}

fn entry(buf: &[u8]) -> Parse<(String, Values<'_>)> {
    let mut r = Reader::new(buf);
    let mut key = String::new();
    // A map entry without a value holds the default `Feature`, which has no list: an empty one.
    let mut values = Values::Bytes(Vec::new());
    while !r.done() {
        match r.tag()? {
            (1, 2) => {
                key = String::from_utf8(r.bytes()?.to_vec())
                    .map_err(|_| "a feature name is not UTF-8".to_string())?;
            }
            (2, 2) => values = feature(r.bytes()?)?,
            (_, w) => r.skip(w)?,
        }
    }
    Ok((key, values))
}

fn feature(buf: &[u8]) -> Parse<Values<'_>> {
    let mut r = Reader::new(buf);
    let mut out = Values::Bytes(Vec::new());
    while !r.done() {
        match r.tag()? {
            (1, 2) => out = Values::Bytes(list_bytes(r.bytes()?)?),
            (2, 2) => out = Values::Float(list_floats(r.bytes()?)?),
            (3, 2) => out = Values::Int64(list_ints(r.bytes()?)?),
            (_, w) => r.skip(w)?,
        }
    }
    Ok(out)
}

fn list_bytes(buf: &[u8]) -> Parse<Vec<&[u8]>> {
    let mut r = Reader::new(buf);
    let mut out = Vec::new();
    while !r.done() {
        match r.tag()? {
            (1, 2) => out.push(r.bytes()?),
            (_, w) => r.skip(w)?,
        }
    }
    Ok(out)
}

fn list_floats(buf: &[u8]) -> Parse<Vec<f32>> {
    let mut r = Reader::new(buf);
    let mut out = Vec::new();
    while !r.done() {
        match r.tag()? {
            (1, 2) => {
                let packed = r.bytes()?;
                if packed.len() % 4 != 0 {
                    return Err(format!("a packed float list of {} bytes", packed.len()));
                }
                out.reserve(packed.len() / 4);
                out.extend(
                    packed
                        .chunks_exact(4)
                        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes"))),
                );
            }
            (1, 5) => out.push(f32::from_bits(r.fixed32()?)),
            (_, w) => r.skip(w)?,
        }
    }
    Ok(out)
}

fn list_ints(buf: &[u8]) -> Parse<Vec<i64>> {
    let mut r = Reader::new(buf);
    let mut out = Vec::new();
    while !r.done() {
        match r.tag()? {
            (1, 2) => {
                let mut p = Reader::new(r.bytes()?);
                while !p.done() {
                    out.push(p.varint()? as i64);
                }
            }
            (1, 0) => out.push(r.varint()? as i64),
            (_, w) => r.skip(w)?,
        }
    }
    Ok(out)
}

/// Encoding, for `chunkc synth` and tests: one Example from its features (packed lists).
pub fn encode(features: &[(&str, Values<'_>)]) -> Vec<u8> {
    fn varint(mut v: u64, out: &mut Vec<u8>) {
        while v >= 0x80 {
            out.push((v as u8) | 0x80);
            v >>= 7;
        }
        out.push(v as u8);
    }
    fn field(number: u64, payload: &[u8], out: &mut Vec<u8>) {
        varint(number << 3 | 2, out);
        varint(payload.len() as u64, out);
        out.extend_from_slice(payload);
    }
    let mut map = Vec::new();
    for (key, values) in features {
        let mut list = Vec::new();
        let number = match values {
            Values::Bytes(v) => {
                for b in v {
                    field(1, b, &mut list);
                }
                1
            }
            Values::Float(v) => {
                let packed: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
                field(1, &packed, &mut list);
                2
            }
            Values::Int64(v) => {
                let mut packed = Vec::new();
                for &x in v {
                    varint(x as u64, &mut packed);
                }
                field(1, &packed, &mut list);
                3
            }
        };
        let mut feature = Vec::new();
        field(number, &list, &mut feature);
        let mut entry = Vec::new();
        field(1, key.as_bytes(), &mut entry);
        field(2, &feature, &mut entry);
        field(1, &entry, &mut map);
    }
    let mut out = Vec::new();
    field(1, &map, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() {
        let jpeg = [0xffu8, 0xd8, 1, 2];
        let features = [
            ("steps/action", Values::Float(vec![1.5, -2.0, 0.25])),
            ("steps/is_first", Values::Int64(vec![1, 0, -3])),
            ("steps/image", Values::Bytes(vec![&jpeg[..], b""])),
        ];
        let bytes = encode(&features);
        let parsed = parse(&bytes).unwrap();
        assert_eq!(parsed.len(), 3);
        for (k, v) in &features {
            assert_eq!(&parsed[*k], v);
        }
    }

    #[test]
    fn accepts_unpacked_numbers_and_refuses_garbage() {
        // FloatList with one unpacked value (field 1, wire type 5) and an Int64List likewise.
        let float_list = [0x0d, 0, 0, 0x80, 0x3f];
        let mut feature = vec![0x12, float_list.len() as u8];
        feature.extend_from_slice(&float_list);
        let mut entry = vec![0x0a, 1, b'x', 0x12, feature.len() as u8];
        entry.extend_from_slice(&feature);
        let mut features = vec![0x0a, entry.len() as u8];
        features.extend_from_slice(&entry);
        let mut example = vec![0x0a, features.len() as u8];
        example.extend_from_slice(&features);
        assert_eq!(parse(&example).unwrap()["x"], Values::Float(vec![1.0]));
        assert!(parse(&[0x0a, 0x7f, 1]).is_err());
        assert!(parse(&[0x0b]).is_err());
    }
}
