// Long file: one file format, its writer, checker and reader side by side (and their round-trip tests), so the layout is written down once.
//! A shard's partial: what the parallel part of the read produced for each of its episodes (the
//! converted low-dim rows, the frames in every encoding the sinks asked for, the statistics
//! partials), in episode order, so that `chunkc merge` can run the sequential part of the same
//! pass (statistics merged in episode order, rows stored, frames written) as if it had read the
//! source itself. Nothing is reduced in a shard that the merge could not redo in the same order,
//! which is why the merged outputs are the single-machine build's bytes.
//!
//! The file: `CHUNKCP1`, a length-prefixed JSON header ([`Header`]: tool version, plan id, shard,
//! episode range), one record per episode, then `END!` and the BLAKE3 of everything before it.
//! Written to a temporary name and renamed, so a shard killed mid-run leaves no partial; the merge
//! checks every checksum before it writes anything. Numbers are little-endian; `f64`/`f32` keep
//! their exact bits.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read as _, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::process::{Prepared, Processed};
use super::rate::Partial;
use crate::error::{Error, IoContext, Result};
use crate::sink::{FrameEncoding, Frames};
use crate::source::video::{PacketSpan, Probe};
use crate::stats::{ImagePartial, Moments};

const MAGIC: &[u8; 8] = b"CHUNKCP1";
const TRAILER: &[u8; 4] = b"END!";
/// Bumped when the record layout changes: a merge never reads a partial of another layout.
pub const PARTIAL_FORMAT: u32 = 2;

/// The partial file of shard `index` of `count` in `dir`.
pub fn path_of(dir: &Path, index: usize, count: usize) -> PathBuf {
    dir.join(format!("shard-{index:05}-of-{count:05}.partial"))
}

/// What a partial says of itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub format: u32,
    pub tool_version: String,
    /// [`crate::plan::shards::plan_id`] of the plan the shard followed.
    pub plan: String,
    pub shard: usize,
    pub shards: usize,
    /// Episode positions (audited manifest order) the records cover.
    pub episodes: [usize; 2],
}

/// One episode's record.
pub(super) enum Record {
    Kept(Processed),
    /// Left out by `[audit] non_finite = "exclude_episode"`, with the reason.
    Excluded(String),
    /// Checked, not kept: an earlier episode of the shard was excluded.
    Checked,
}

/// Writes a partial record by record; [`Writer::finish`] makes it visible.
pub(super) struct Writer {
    out: BufWriter<File>,
    hasher: blake3::Hasher,
    tmp: PathBuf,
    path: PathBuf,
}

impl Writer {
    pub fn create(path: &Path, header: &Header) -> Result<Writer> {
        let tmp = path.with_extension("partial.tmp");
        let file = File::create(&tmp).at("create", &tmp)?;
        let mut w = Writer {
            out: BufWriter::with_capacity(1 << 20, file),
            hasher: blake3::Hasher::new(),
            tmp,
            path: path.to_path_buf(),
        };
        let json = serde_json::to_vec(header).expect("a header serializes");
        w.bytes(MAGIC)?;
        w.u64(json.len() as u64)?;
        w.bytes(&json)?;
        Ok(w)
    }

    fn bytes(&mut self, b: &[u8]) -> Result<()> {
        self.hasher.update(b);
        self.out.write_all(b).at("write", &self.tmp)
    }

    fn u8(&mut self, v: u8) -> Result<()> {
        self.bytes(&[v])
    }

    fn u64(&mut self, v: u64) -> Result<()> {
        self.bytes(&v.to_le_bytes())
    }

    fn f64s(&mut self, v: &[f64]) -> Result<()> {
        self.u64(v.len() as u64)?;
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.bytes(&bytes)
    }

    fn moments(&mut self, m: &Moments) -> Result<()> {
        self.u64(m.count)?;
        for v in [&m.mean, &m.m2, &m.min, &m.max] {
            self.f64s(v)?;
        }
        Ok(())
    }

    fn frames(&mut self, encoding: FrameEncoding, frames: &Frames) -> Result<()> {
        let (kind, level) = encoding_code(encoding);
        self.bytes(&[kind, level])?;
        self.u64(frames.bytes().len() as u64)?;
        self.bytes(frames.bytes())?;
        let ends = frames.ends();
        self.u64(ends.len() as u64)?;
        let bytes: Vec<u8> = ends.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.bytes(&bytes)?;
        self.packets(frames.packets())
    }

    fn text(&mut self, s: &str) -> Result<()> {
        self.u64(s.len() as u64)?;
        self.bytes(s.as_bytes())
    }

    /// The video packets the frames are the decode of: 0, or 1 and where they are.
    fn packets(&mut self, span: Option<&PacketSpan>) -> Result<()> {
        let Some(span) = span else { return self.u8(0) };
        self.u8(1)?;
        let file = span.file.to_str().ok_or_else(|| {
            Error::output(format!("{}: the path is not UTF-8", span.file.display()))
        })?;
        self.text(file)?;
        self.text(&span.probe.codec)?;
        self.u64(span.probe.width as u64)?;
        self.u64(span.probe.height as u64)?;
        self.u64(span.first.to_bits())?;
        self.u64(span.last.to_bits())?;
        self.u64(span.frames as u64)
    }

    pub fn record(&mut self, record: &Record) -> Result<()> {
        match record {
            Record::Checked => self.u8(2),
            Record::Excluded(reason) => {
                self.u8(1)?;
                self.u64(reason.len() as u64)?;
                self.bytes(reason.as_bytes())
            }
            Record::Kept(p) => {
                self.u8(0)?;
                self.u64(p.data.len() as u64)?;
                for (data, partials) in p.data.iter().zip(&p.partials) {
                    self.u64(data.len() as u64)?;
                    for (values, partial) in data.iter().zip(partials) {
                        match values {
                            Prepared::Lowdim(v) => {
                                self.u8(0)?;
                                self.u64(v.len() as u64)?;
                                self.bytes(crate::bytes::f32_bytes(v))?;
                            }
                            Prepared::Frames(encoded) => {
                                self.u8(1)?;
                                self.u64(encoded.len() as u64)?;
                                for (enc, frames) in encoded {
                                    self.frames(*enc, frames)?;
                                }
                            }
                        }
                        match partial {
                            None => self.u8(0)?,
                            Some(Partial::Lowdim(m)) => {
                                self.u8(1)?;
                                self.moments(m)?;
                            }
                            Some(Partial::Image(img)) => {
                                self.u8(2)?;
                                self.u64(img.frames)?;
                                self.moments(&img.moments)?;
                                self.u64(img.hist.len() as u64)?;
                                let bytes: Vec<u8> = img
                                    .hist
                                    .iter()
                                    .flat_map(|h| h.iter().flat_map(|x| x.to_le_bytes()))
                                    .collect();
                                self.bytes(&bytes)?;
                            }
                        }
                    }
                }
                Ok(())
            }
        }
    }

    /// Writes the trailer, syncs and renames the partial into place.
    pub fn finish(mut self) -> Result<()> {
        self.bytes(TRAILER)?;
        let digest = *self.hasher.finalize().as_bytes();
        self.out.write_all(&digest).at("write", &self.tmp)?;
        let file = self
            .out
            .into_inner()
            .map_err(|e| Error::io_path("write", &self.tmp, e.into_error()))?;
        file.sync_all().at("sync", &self.tmp)?;
        std::fs::rename(&self.tmp, &self.path).at("rename into place", &self.path)
    }
}

fn encoding_code(e: FrameEncoding) -> (u8, u8) {
    match e {
        FrameEncoding::Raw => (0, 0),
        FrameEncoding::Zlib(level) => (1, level),
        FrameEncoding::Png => (2, 0),
        FrameEncoding::Jpeg(quality) => (3, quality),
    }
}

fn encoding_of(kind: u8, level: u8) -> Option<FrameEncoding> {
    match kind {
        0 => Some(FrameEncoding::Raw),
        1 => Some(FrameEncoding::Zlib(level)),
        2 => Some(FrameEncoding::Png),
        3 => Some(FrameEncoding::Jpeg(level)),
        _ => None,
    }
}

/// Reads a partial's header and checks its checksum and framing (the whole file is read once;
/// nothing is kept).
pub fn verify(path: &Path) -> Result<Header> {
    let bad = |what: &str| Error::source(format!("{}: {what}", path.display()));
    let mut file = BufReader::with_capacity(1 << 20, File::open(path).at("open", path)?);
    let len = std::fs::metadata(path).at("read", path)?.len();
    if len < (MAGIC.len() + 8 + TRAILER.len() + 32) as u64 {
        return Err(bad("truncated: too short to be a chunkc partial"));
    }
    let body = len - 32;
    let mut hasher = blake3::Hasher::new();
    let mut left = body;
    let mut buf = vec![0u8; 1 << 20];
    let mut head = Vec::new();
    while left > 0 {
        let n = (left as usize).min(buf.len());
        file.read_exact(&mut buf[..n]).at("read", path)?;
        if head.len() < 1 << 16 {
            head.extend_from_slice(&buf[..n.min((1 << 16) - head.len())]);
        }
        hasher.update(&buf[..n]);
        left -= n as u64;
    }
    let mut digest = [0u8; 32];
    file.read_exact(&mut digest).at("read", path)?;
    if &head[..MAGIC.len()] != MAGIC {
        return Err(bad("not a chunkc partial (no CHUNKCP1 magic)"));
    }
    if digest != *hasher.finalize().as_bytes() {
        return Err(bad(
            "checksum mismatch: the partial is truncated or damaged; run its shard again",
        ));
    }
    parse_header(&head[MAGIC.len()..]).ok_or_else(|| bad("unreadable header"))
}

fn parse_header(bytes: &[u8]) -> Option<Header> {
    let len = u64::from_le_bytes(bytes.get(..8)?.try_into().ok()?) as usize;
    serde_json::from_slice(bytes.get(8..8 + len)?).ok()
}

/// Reads a verified partial's records in order.
pub(super) struct Reader {
    input: BufReader<File>,
    path: PathBuf,
    pub header: Header,
}

impl Reader {
    pub fn open(path: &Path) -> Result<Reader> {
        let mut input = BufReader::with_capacity(1 << 20, File::open(path).at("open", path)?);
        let mut magic = [0u8; 8];
        input.read_exact(&mut magic).at("read", path)?;
        let mut r = Reader {
            input,
            path: path.to_path_buf(),
            header: Header {
                format: 0,
                tool_version: String::new(),
                plan: String::new(),
                shard: 0,
                shards: 0,
                episodes: [0, 0],
            },
        };
        let len = r.u64()? as usize;
        let json = r.take(len)?;
        r.header = serde_json::from_slice(&json).map_err(|e| r.bad(&format!("header: {e}")))?;
        Ok(r)
    }

    /// The episode positions the records cover.
    pub fn episodes(&self) -> Range<usize> {
        self.header.episodes[0]..self.header.episodes[1]
    }

    fn bad(&self, what: &str) -> Error {
        Error::source(format!("{}: {what}", self.path.display()))
    }

    fn take(&mut self, n: usize) -> Result<Vec<u8>> {
        let mut v = vec![0u8; n];
        self.input.read_exact(&mut v).at("read", &self.path)?;
        Ok(v)
    }

    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }

    fn u64(&mut self) -> Result<u64> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }

    fn u64s(&mut self) -> Result<Vec<u64>> {
        let n = self.u64()? as usize;
        let b = self.take(8 * n)?;
        Ok(b.chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }

    fn f64s(&mut self) -> Result<Vec<f64>> {
        Ok(self.u64s()?.into_iter().map(f64::from_bits).collect())
    }

    fn text(&mut self) -> Result<String> {
        let n = self.u64()? as usize;
        String::from_utf8(self.take(n)?).map_err(|_| self.bad("damaged text"))
    }

    fn packets(&mut self) -> Result<Option<PacketSpan>> {
        if self.u8()? == 0 {
            return Ok(None);
        }
        let file = PathBuf::from(self.text()?);
        let probe = Probe {
            codec: self.text()?,
            width: self.u64()? as usize,
            height: self.u64()? as usize,
        };
        Ok(Some(PacketSpan {
            file,
            probe,
            first: f64::from_bits(self.u64()?),
            last: f64::from_bits(self.u64()?),
            frames: self.u64()? as usize,
        }))
    }

    fn moments(&mut self) -> Result<Moments> {
        Ok(Moments {
            count: self.u64()?,
            mean: self.f64s()?,
            m2: self.f64s()?,
            min: self.f64s()?,
            max: self.f64s()?,
        })
    }

    pub fn record(&mut self) -> Result<Record> {
        match self.u8()? {
            2 => Ok(Record::Checked),
            1 => {
                let n = self.u64()? as usize;
                let reason = String::from_utf8(self.take(n)?).map_err(|_| self.bad("reason"))?;
                Ok(Record::Excluded(reason))
            }
            0 => {
                let rates = self.u64()? as usize;
                let mut data = Vec::with_capacity(rates);
                let mut partials = Vec::with_capacity(rates);
                for _ in 0..rates {
                    let channels = self.u64()? as usize;
                    let (mut d, mut p) = (Vec::new(), Vec::new());
                    for _ in 0..channels {
                        d.push(match self.u8()? {
                            0 => {
                                let n = self.u64()? as usize;
                                let b = self.take(4 * n)?;
                                Prepared::Lowdim(
                                    b.chunks_exact(4)
                                        .map(|c| f32::from_le_bytes(c.try_into().expect("4")))
                                        .collect(),
                                )
                            }
                            1 => {
                                let n = self.u64()? as usize;
                                let mut encoded = Vec::with_capacity(n);
                                for _ in 0..n {
                                    let (kind, level) = (self.u8()?, self.u8()?);
                                    let enc = encoding_of(kind, level)
                                        .ok_or_else(|| self.bad("unknown frame encoding"))?;
                                    let len = self.u64()? as usize;
                                    let bytes = self.take(len)?;
                                    let ends = self.u64s()?;
                                    let packets = self.packets()?;
                                    let frames = Frames::from_parts(bytes, ends);
                                    encoded.push((enc, frames.with_packets(packets)));
                                }
                                Prepared::Frames(encoded)
                            }
                            _ => return Err(self.bad("damaged record")),
                        });
                        p.push(match self.u8()? {
                            0 => None,
                            1 => Some(Partial::Lowdim(self.moments()?)),
                            2 => {
                                let frames = self.u64()?;
                                let moments = self.moments()?;
                                let colors = self.u64()? as usize;
                                let flat = {
                                    let b = self.take(8 * 256 * colors)?;
                                    b.chunks_exact(8)
                                        .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
                                        .collect::<Vec<u64>>()
                                };
                                let hist = flat
                                    .chunks_exact(256)
                                    .map(|h| h.try_into().expect("256 bins"))
                                    .collect();
                                Some(Partial::Image(ImagePartial {
                                    frames,
                                    moments,
                                    hist,
                                }))
                            }
                            _ => return Err(self.bad("damaged record")),
                        });
                    }
                    data.push(d);
                    partials.push(p);
                }
                Ok(Record::Kept(Processed { data, partials }))
            }
            _ => Err(self.bad("damaged record")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Processed {
        let frames = Frames::encode(FrameEncoding::Zlib(4), &[7u8; 2 * 12], &[2, 2, 3]);
        let mut img = ImagePartial::of_frames(&[7u8; 2 * 12], 2, 3);
        img.hist[1][9] = 3;
        Processed {
            data: vec![vec![
                Prepared::Lowdim(vec![1.5, -0.0, f32::MIN_POSITIVE, 3.25]),
                Prepared::Frames(vec![
                    (FrameEncoding::Zlib(4), frames),
                    (
                        FrameEncoding::Raw,
                        Frames::raw(vec![7u8; 24], 12).with_packets(Some(PacketSpan {
                            file: "/data/videos/file-000.mp4".into(),
                            probe: Probe {
                                codec: "av1".into(),
                                width: 2,
                                height: 2,
                            },
                            first: 0.1,
                            last: 0.2,
                            frames: 2,
                        })),
                    ),
                ]),
            ]],
            partials: vec![vec![
                Some(Partial::Lowdim(Moments::of_rows(
                    &[1.5, -0.0, 0.1, 3.25],
                    2,
                ))),
                Some(Partial::Image(img)),
            ]],
        }
    }

    fn written(dir: &Path, records: &[Record]) -> PathBuf {
        let path = path_of(dir, 1, 3);
        let header = Header {
            format: PARTIAL_FORMAT,
            tool_version: "t".into(),
            plan: "p".into(),
            shard: 1,
            shards: 3,
            episodes: [4, 4 + records.len()],
        };
        let mut w = Writer::create(&path, &header).unwrap();
        for r in records {
            w.record(r).unwrap();
        }
        w.finish().unwrap();
        path
    }

    #[test]
    fn records_round_trip_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = written(
            dir.path(),
            &[Record::Kept(sample()), Record::Excluded("nan".into())],
        );
        assert_eq!(verify(&path).unwrap().episodes, [4, 6]);
        let mut r = Reader::open(&path).unwrap();
        let Record::Kept(p) = r.record().unwrap() else {
            panic!("kept")
        };
        let want = sample();
        match (&p.data[0][0], &want.data[0][0]) {
            (Prepared::Lowdim(a), Prepared::Lowdim(b)) => {
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(a), bits(b));
            }
            _ => panic!("lowdim"),
        }
        match (&p.data[0][1], &want.data[0][1]) {
            (Prepared::Frames(a), Prepared::Frames(b)) => assert_eq!(a, b),
            _ => panic!("frames"),
        }
        match (&p.partials[0][0], &want.partials[0][0]) {
            (Some(Partial::Lowdim(a)), Some(Partial::Lowdim(b))) => assert_eq!(a, b),
            _ => panic!("moments"),
        }
        match (&p.partials[0][1], &want.partials[0][1]) {
            (Some(Partial::Image(a)), Some(Partial::Image(b))) => {
                assert_eq!(
                    (a.frames, &a.moments, &a.hist),
                    (b.frames, &b.moments, &b.hist)
                )
            }
            _ => panic!("image"),
        }
        assert!(matches!(r.record().unwrap(), Record::Excluded(s) if s == "nan"));
    }

    #[test]
    fn a_damaged_or_truncated_partial_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = written(dir.path(), &[Record::Kept(sample())]);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[100] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        let err = verify(&path).unwrap_err().to_string();
        assert!(err.contains("checksum mismatch"), "{err}");
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        assert!(verify(&path)
            .unwrap_err()
            .to_string()
            .contains("checksum mismatch"));
    }
}
