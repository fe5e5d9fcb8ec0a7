//! Checking a partial whole, then reading its records back in order (the layout: [`super`]).

use std::fs::File;
use std::io::{BufReader, Read as _};
use std::ops::Range;
use std::path::{Path, PathBuf};

use super::{encoding_of, Header, Record, MAGIC, PIXELLESS, TRAILER};
use crate::error::{Error, IoContext, Result};
use crate::exec::process::{Prepared, Processed};
use crate::exec::rate::Partial;
use crate::sink::{FrameEncoding, Frames};
use crate::source::video::{PacketSpan, Probe};
use crate::stats::{ImagePartial, Moments};

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
pub(in crate::exec) struct Reader {
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

    fn frames(&mut self) -> Result<(FrameEncoding, Frames)> {
        let (kind, level) = (self.u8()?, self.u8()?);
        let len = self.u64()? as usize;
        let bytes = self.take(len)?;
        let ends = self.u64s()?;
        let packets = self.packets()?;
        if kind == PIXELLESS {
            let packets =
                packets.ok_or_else(|| self.bad("frames with neither pixels nor packets"))?;
            return Ok((FrameEncoding::Raw, Frames::pixelless(ends, packets)));
        }
        let enc = encoding_of(kind, level).ok_or_else(|| self.bad("unknown frame encoding"))?;
        Ok((enc, Frames::from_parts(bytes, ends).with_packets(packets)))
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
                                    encoded.push(self.frames()?);
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
