//! Writing a partial, record by record (the layout: [`super`]).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::{encoding_code, Header, Record, MAGIC, PIXELLESS, TRAILER};
use crate::error::{Error, IoContext, Result};
use crate::exec::process::Prepared;
use crate::exec::rate::Partial;
use crate::sink::{FrameEncoding, Frames};
use crate::source::video::PacketSpan;
use crate::stats::Moments;

/// Writes a partial record by record; [`Writer::finish`] makes it visible.
pub(in crate::exec) struct Writer {
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
        // Frames whose pixels were left behind (every sink copies their packets) are a kind of
        // their own: their ends and packets, no pixels.
        let kind = if frames.has_pixels() { kind } else { PIXELLESS };
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
