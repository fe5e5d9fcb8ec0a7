// Long file: one parser: the HDF5 superblock, object headers and their messages, read without the library.
//! Where a contiguous dataset lies in an HDF5 file, read from the file's own metadata without the
//! HDF5 library.
//!
//! Every call into HDF5 holds its global lock, and opening a file costs tens of microseconds of
//! it (a metadata cache is created and torn down each time), so the per-file headers of a
//! directory of episodes were read one file at a time. This reader understands the small part of
//! the format those headers need, enough for what h5py, ACT's recorder and `chunkc synth` write:
//! superblocks 0-3 (8-byte offsets and lengths, no user block), object headers v1 and v2 with
//! continuation blocks, groups as symbol tables (v1 B-tree + local heap) or as compact link
//! messages, and per dataset the dataspace, the datatype (little-endian IEEE `f32`/`f64` and
//! `u8`) and a contiguous layout (v3/v4). Anything else (dense groups, chunked or compact data,
//! external storage, filters, shared messages, big-endian or unusual types, soft links) makes it
//! answer `None`, and the caller reads that file through HDF5 as before. It reads bytes only,
//! never panics on bad input, and checks that the data lies inside the file.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;

use super::h5::{Direct, DirectType, Place};

/// An undefined address (all ones).
const UNDEF: u64 = u64::MAX;
/// Object header continuation blocks followed before giving up (a loop guard).
const MAX_BLOCKS: usize = 64;
/// B-tree nodes visited in one group lookup (a loop guard).
const MAX_NODES: usize = 4096;

/// A dataset's per-file facts: its shape and where its values lie.
#[derive(Debug, Clone, PartialEq)]
pub struct Located {
    pub shape: Vec<usize>,
    pub direct: Direct,
}

/// Locates each of `keys` (paths from the root group, `a/b/c`) in the file at `path`; `None` when
/// any of them is outside what this reader understands (see the module docs).
pub fn locate(path: &Path, keys: &[String]) -> Option<Vec<Located>> {
    let file = File::open(path).ok()?;
    let size = file.metadata().ok()?.len();
    let r = Reader { file, size };
    let root = r.root()?;
    keys.iter()
        .map(|key| {
            let mut object = root;
            for part in key.split('/').filter(|p| !p.is_empty()) {
                object = r.child(object, part)?;
            }
            r.dataset(object)
        })
        .collect()
}

struct Reader {
    file: File,
    size: u64,
}

/// One object header message.
struct Message {
    kind: u16,
    flags: u8,
    data: Vec<u8>,
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

/// A little-endian unsigned integer of `n` (1, 2, 4 or 8) bytes.
fn uint_at(b: &[u8], at: usize, n: usize) -> Option<u64> {
    let bytes = b.get(at..at + n)?;
    let mut v = 0u64;
    for (i, &x) in bytes.iter().enumerate() {
        v |= u64::from(x) << (8 * i);
    }
    Some(v)
}

impl Reader {
    fn read(&self, at: u64, len: usize) -> Option<Vec<u8>> {
        if at == UNDEF || at.checked_add(len as u64)? > self.size || len > (64 << 20) {
            return None;
        }
        let mut buf = vec![0u8; len];
        self.file.read_exact_at(&mut buf, at).ok()?;
        Some(buf)
    }

    /// The root group's object header address.
    fn root(&self) -> Option<u64> {
        let sb = self.read(0, 96.min(self.size as usize))?;
        if sb.get(..8)? != b"\x89HDF\r\n\x1a\n" {
            return None;
        }
        match sb[8] {
            0 | 1 => {
                // Sizes of offsets and lengths at 13 and 14; version 1 adds 4 bytes of B-tree K.
                if sb.get(13..15)? != [8, 8] {
                    return None;
                }
                let base = if sb[8] == 0 { 24 } else { 28 };
                if u64_at(&sb, base)? != 0 {
                    return None;
                }
                // Base, free-space, end-of-file and driver addresses, then the root group's
                // symbol table entry: link name offset, object header address.
                u64_at(&sb, base + 4 * 8 + 8)
            }
            2 | 3 => {
                if sb.get(9..11)? != [8, 8] || u64_at(&sb, 12)? != 0 {
                    return None;
                }
                // Base, superblock extension, end of file, root object header.
                u64_at(&sb, 12 + 3 * 8)
            }
            _ => None,
        }
    }

    /// Every message of the object header at `at`, continuation blocks included.
    fn messages(&self, at: u64) -> Option<Vec<Message>> {
        let head = self.read(at, 16.min((self.size - at.min(self.size)) as usize))?;
        if head.get(..4)? == b"OHDR" {
            return self.messages_v2(at);
        }
        if *head.first()? != 1 {
            return None;
        }
        let count = u16_at(&head, 2)? as usize;
        let first_len = u32_at(&head, 8)? as usize;
        let mut blocks = vec![(at + 16, first_len)];
        let mut out = Vec::new();
        let mut i = 0;
        while i < blocks.len() && out.len() < count {
            if i >= MAX_BLOCKS {
                return None;
            }
            let (addr, len) = blocks[i];
            let block = self.read(addr, len)?;
            let mut p = 0;
            while p + 8 <= block.len() && out.len() < count {
                let kind = u16_at(&block, p)?;
                let size = u16_at(&block, p + 2)? as usize;
                let flags = block[p + 4];
                let data = block.get(p + 8..p + 8 + size)?.to_vec();
                if kind == 0x10 {
                    blocks.push((u64_at(&data, 0)?, u64_at(&data, 8)? as usize));
                }
                out.push(Message { kind, flags, data });
                p += 8 + size;
            }
            i += 1;
        }
        Some(out)
    }

    fn messages_v2(&self, at: u64) -> Option<Vec<Message>> {
        let prefix = self.read(at, 32.min((self.size - at) as usize))?;
        if prefix[4] != 2 {
            return None;
        }
        let flags = prefix[5];
        let mut p = 6;
        if flags & 0x20 != 0 {
            p += 16;
        }
        if flags & 0x10 != 0 {
            p += 4;
        }
        let width = 1usize << (flags & 3);
        let chunk0 = uint_at(&prefix, p, width)? as usize;
        p += width;
        let order = flags & 0x04 != 0;
        let mut blocks = vec![(at + p as u64, chunk0)];
        let mut out = Vec::new();
        let mut i = 0;
        while i < blocks.len() {
            if i >= MAX_BLOCKS {
                return None;
            }
            let (addr, len) = blocks[i];
            let block = self.read(addr, len)?;
            let head = if order { 6 } else { 4 };
            let mut q = 0;
            while q + head <= block.len() {
                let kind = u16::from(block[q]);
                let size = u16_at(&block, q + 1)? as usize;
                let mflags = block[q + 3];
                let data = block.get(q + head..q + head + size)?.to_vec();
                if kind == 0x10 {
                    // A continuation block: "OCHK", messages, checksum.
                    let (caddr, clen) = (u64_at(&data, 0)?, u64_at(&data, 8)? as usize);
                    if self.read(caddr, 4)? != b"OCHK" || clen < 8 {
                        return None;
                    }
                    blocks.push((caddr + 4, clen - 8));
                }
                out.push(Message {
                    kind,
                    flags: mflags,
                    data,
                });
                q += head + size;
            }
            i += 1;
        }
        Some(out)
    }

    /// The object header address of the member `name` of the group at `group`.
    fn child(&self, group: u64, name: &str) -> Option<u64> {
        let messages = self.messages(group)?;
        for m in &messages {
            match m.kind {
                // Link info: dense storage (a fractal heap) is not read here.
                0x02 => {
                    let heap_at = 1 + 1 + if m.data.get(1)? & 1 != 0 { 8 } else { 0 };
                    if u64_at(&m.data, heap_at)? != UNDEF {
                        return None;
                    }
                }
                0x06 => {
                    if let Some((link, addr)) = link(&m.data) {
                        if link == name {
                            return addr;
                        }
                    }
                }
                0x11 => {
                    let (btree, heap) = (u64_at(&m.data, 0)?, u64_at(&m.data, 8)?);
                    return self.symbol_table(btree, heap, name);
                }
                _ => {}
            }
        }
        None
    }

    /// Looks `name` up in a v1 group B-tree with its local heap of names.
    fn symbol_table(&self, btree: u64, heap: u64, name: &str) -> Option<u64> {
        let h = self.read(heap, 32)?;
        if h.get(..4)? != b"HEAP" {
            return None;
        }
        let (heap_size, heap_data) = (u64_at(&h, 8)? as usize, u64_at(&h, 24)?);
        let names = self.read(heap_data, heap_size)?;
        let name_at = |offset: u64| -> Option<&[u8]> {
            let rest = names.get(offset as usize..)?;
            let end = rest.iter().position(|&b| b == 0)?;
            Some(&rest[..end])
        };
        let mut stack = vec![btree];
        let mut visited = 0;
        while let Some(node) = stack.pop() {
            visited += 1;
            if visited > MAX_NODES {
                return None;
            }
            let head = self.read(node, 24)?;
            if head.get(..4)? != b"TREE" || head[4] != 0 {
                return None;
            }
            let level = head[5];
            let entries = u16_at(&head, 6)? as usize;
            // Keys (8-byte heap offsets) and children (8-byte addresses), interleaved.
            let body = self.read(node + 24, (2 * entries + 1) * 8)?;
            for e in 0..entries {
                let child = u64_at(&body, 8 + 16 * e)?;
                if level > 0 {
                    stack.push(child);
                    continue;
                }
                let snod = self.read(child, 8)?;
                if snod.get(..4)? != b"SNOD" {
                    return None;
                }
                let symbols = u16_at(&snod, 6)? as usize;
                let table = self.read(child + 8, symbols * 40)?;
                for s in 0..symbols {
                    let entry = &table[40 * s..40 * s + 40];
                    if name_at(u64_at(entry, 0)?)? == name.as_bytes() {
                        return u64_at(entry, 8);
                    }
                }
            }
        }
        None
    }

    /// The shape and location of the dataset at `at`.
    fn dataset(&self, at: u64) -> Option<Located> {
        let messages = self.messages(at)?;
        let (mut shape, mut dtype, mut place) = (None, None, None);
        for m in &messages {
            // Shared messages live elsewhere: not read here.
            if m.flags & 0x02 != 0 && matches!(m.kind, 0x01 | 0x03 | 0x08) {
                return None;
            }
            match m.kind {
                0x01 => shape = Some(dataspace(&m.data)?),
                0x03 => dtype = Some(datatype(&m.data)?),
                0x08 => place = Some(contiguous(&m.data)?),
                // External storage or a filter pipeline.
                0x07 | 0x0B => return None,
                _ => {}
            }
        }
        let (shape, dtype, (offset, bytes)) = (shape?, dtype?, place?);
        let elements = shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d))?;
        let size = match dtype {
            DirectType::F32 => 4,
            DirectType::F64 => 8,
            DirectType::U8 => 1,
        };
        if elements.checked_mul(size)? as u64 != bytes || offset.checked_add(bytes)? > self.size {
            return None;
        }
        Some(Located {
            shape,
            direct: Direct {
                place: Place::Contiguous(offset),
                elements,
                dtype,
            },
        })
    }
}

/// A link message: its name, and the target address of a hard link (`None` for soft and
/// external links).
fn link(d: &[u8]) -> Option<(String, Option<u64>)> {
    if *d.first()? != 1 {
        return None;
    }
    let flags = d[1];
    let mut p = 2;
    let mut kind = 0;
    if flags & 0x08 != 0 {
        kind = *d.get(p)?;
        p += 1;
    }
    if flags & 0x04 != 0 {
        p += 8;
    }
    if flags & 0x10 != 0 {
        p += 1;
    }
    let width = 1usize << (flags & 3);
    let len = uint_at(d, p, width)? as usize;
    p += width;
    let name = String::from_utf8(d.get(p..p + len)?.to_vec()).ok()?;
    p += len;
    Some((name, if kind == 0 { u64_at(d, p) } else { None }))
}

/// A simple dataspace's dimensions (versions 1 and 2).
fn dataspace(d: &[u8]) -> Option<Vec<usize>> {
    let (version, rank) = (*d.first()?, *d.get(1)? as usize);
    let start = match version {
        1 => 8,
        2 if *d.get(3)? == 1 => 4,
        _ => return None,
    };
    (0..rank)
        .map(|i| usize::try_from(u64_at(d, start + 8 * i)?).ok())
        .collect()
}

/// The element types read directly: little-endian IEEE `f32`/`f64` and `u8`.
fn datatype(d: &[u8]) -> Option<DirectType> {
    let class = d.first()? & 0x0F;
    let bits = *d.get(1)?;
    let size = u32_at(d, 4)?;
    match (class, size) {
        // Floating point: little-endian (bits 0 and 6 clear), standard IEEE fields.
        (1, 4 | 8) => {
            let (offset, precision) = (u16_at(d, 8)?, u16_at(d, 10)?);
            let (exp_at, exp_bits, man_at, man_bits) = (d[12], d[13], d[14], d[15]);
            let bias = u32_at(d, 16)?;
            let ieee = match size {
                4 => {
                    (precision, exp_at, exp_bits, man_at, man_bits, bias) == (32, 23, 8, 0, 23, 127)
                }
                _ => {
                    (precision, exp_at, exp_bits, man_at, man_bits, bias)
                        == (64, 52, 11, 0, 52, 1023)
                }
            };
            (bits & 0x41 == 0 && offset == 0 && ieee).then_some(if size == 4 {
                DirectType::F32
            } else {
                DirectType::F64
            })
        }
        // Fixed point, one byte, unsigned (bit 3 clear), all 8 bits used.
        (0, 1) => {
            let (offset, precision) = (u16_at(d, 8)?, u16_at(d, 10)?);
            (bits & 0x08 == 0 && offset == 0 && precision == 8).then_some(DirectType::U8)
        }
        _ => None,
    }
}

/// A contiguous layout's address and size (layout message versions 3 and 4), when allocated.
fn contiguous(d: &[u8]) -> Option<(u64, u64)> {
    if !matches!(d.first()?, 3 | 4) || *d.get(1)? != 1 {
        return None;
    }
    let (offset, size) = (u64_at(d, 2)?, u64_at(d, 10)?);
    (offset != UNDEF).then_some((offset, size))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::h5;

    /// Every dataset of `path`: what this reader says against what HDF5 says.
    fn agrees_with_hdf5(path: &Path) -> usize {
        let file = h5::open(path).unwrap();
        let mut located = 0;
        for (key, ds) in h5::datasets(&file, path).unwrap() {
            let ours = locate(path, std::slice::from_ref(&key)).map(|mut v| v.remove(0));
            match (h5::direct(&ds), ours) {
                (Some(d), Some(o)) => {
                    assert_eq!(o.direct, d, "{}: {key}", path.display());
                    assert_eq!(o.shape, ds.shape(), "{}: {key}", path.display());
                    located += 1;
                }
                (None, Some(o)) => panic!("{}: {key}: HDF5 reads it, we say {o:?}", path.display()),
                // Not understood here: the caller reads it through HDF5.
                (_, None) => {}
            }
        }
        located
    }

    #[test]
    fn locates_what_hdf5_locates_in_h5py_files() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        let mut located = 0;
        for name in [
            "robosuite_panda_lift.hdf5",
            "robosuite_sawyer_lift.hdf5",
            "robosuite_baxter_peg_in_hole.hdf5",
        ] {
            let path = data.join(name);
            assert_eq!(std::fs::read(&path).unwrap()[8], 0, "superblock 0 (h5py)");
            located += agrees_with_hdf5(&path);
        }
        assert!(located > 10, "only {located} datasets located");
    }

    #[test]
    fn locates_what_hdf5_locates_in_files_written_by_the_hdf5_library() {
        // This HDF5 build writes superblock 2 and v2 object headers (compact groups of link
        // messages) whether or not times are tracked; h5py's files (superblock 0, symbol
        // tables) are the test above.
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.hdf5");
        written(hdf5::File::create(&plain).unwrap());
        let untimed = dir.path().join("untimed.hdf5");
        written(
            hdf5::File::with_options()
                .with_fcpl(|p| p.obj_track_times(false))
                .create(&untimed)
                .unwrap(),
        );
        let version = |p: &Path| std::fs::read(p).unwrap()[8];
        assert_eq!((version(&plain), version(&untimed)), (2, 2));
        for path in [plain, untimed] {
            assert!(agrees_with_hdf5(&path) >= 3, "{}", path.display());
            let keys = ["action".to_string(), "observations/qpos".to_string()];
            let found = locate(&path, &keys).expect("both contiguous");
            assert_eq!(found[1].shape, vec![20, 3]);
            assert_eq!(found[1].direct.dtype, DirectType::F32);
            assert_eq!(found[0].direct.dtype, DirectType::F64);
            assert!(locate(&path, &["observations/images/cam".to_string()]).is_none());
            assert!(locate(&path, &["nothing".to_string()]).is_none());
            assert!(locate(&path, &["many/x3".to_string()]).is_none());
        }
    }

    fn written(f: hdf5::File) {
        {
            let obs = f.create_group("observations").unwrap();
            let images = obs.create_group("images").unwrap();
            let q: Vec<f32> = (0..60).map(|i| i as f32 * 0.5).collect();
            obs.new_dataset::<f32>()
                .shape([20, 3])
                .create("qpos")
                .unwrap()
                .write_raw(&q)
                .unwrap();
            let a: Vec<f64> = (0..40).map(|i| i as f64).collect();
            f.new_dataset::<f64>()
                .shape([20, 2])
                .create("action")
                .unwrap()
                .write_raw(&a)
                .unwrap();
            let px = vec![7u8; 20 * 4 * 4 * 3];
            images
                .new_dataset::<u8>()
                .shape([20, 4, 4, 3])
                .chunk([1, 4, 4, 3])
                .create("cam")
                .unwrap()
                .write_raw(&px)
                .unwrap();
            images
                .new_dataset::<u8>()
                .shape([20, 4, 4, 3])
                .create("flat")
                .unwrap()
                .write_raw(&px)
                .unwrap();
            // More members than a compact group holds: dense storage, which is not read here.
            let many = f.create_group("many").unwrap();
            for i in 0..20 {
                many.new_dataset::<f32>()
                    .shape([2])
                    .create(format!("x{i}").as_str())
                    .unwrap()
                    .write_raw(&[1.0f32, 2.0])
                    .unwrap();
            }
        }
    }

    #[test]
    fn never_panics_on_damaged_files() {
        let dir = tempfile::tempdir().unwrap();
        let src =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/robosuite_panda_lift.hdf5");
        let bytes = std::fs::read(src).unwrap();
        let path = dir.path().join("x.hdf5");
        let keys = ["data/demo_0/actions".to_string()];
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        for round in 0..300 {
            let mut b = bytes[..bytes.len().min(64 << 10)].to_vec();
            for _ in 0..(1 + round % 8) {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let at = (state as usize) % b.len();
                b[at] = (state >> 32) as u8;
            }
            std::fs::write(&path, &b).unwrap();
            let _ = locate(&path, &keys);
        }
    }
}
