//! One episode's frames of a camera as a sink takes them: encoded the way the sink asked
//! ([`FrameEncoding`]), with the video packets they are the decode of where nothing changed them,
//! so that a video sink may copy those packets instead of encoding the pixels.

use std::sync::Arc;

use super::{jpeg, png};
use crate::source::video::PacketSpan;
use crate::window::Ends;

/// How a sink wants image frames handed to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FrameEncoding {
    /// The frame's bytes as they are (HWC `u8`).
    Raw,
    /// A zlib stream at this level: what HDF5's deflate filter stores as a chunk.
    Zlib(u8),
    /// A PNG file ([`png::encode`]): what LeRobot stores in parquet.
    Png,
    /// A JPEG file at this quality ([`jpeg::encode`]): what `image_compression = "jpeg"` stores.
    Jpeg(u8),
}

/// Encodes one `u8` frame of `shape` (HWC).
pub fn encode_frame(encoding: FrameEncoding, frame: &[u8], shape: &[usize]) -> Vec<u8> {
    match encoding {
        FrameEncoding::Raw => frame.to_vec(),
        FrameEncoding::Png => png::encode(frame, shape),
        FrameEncoding::Jpeg(quality) => jpeg::encode(frame, shape, quality),
        FrameEncoding::Zlib(level) => {
            use std::io::Write;
            let mut enc = flate2::write::ZlibEncoder::new(
                Vec::with_capacity(frame.len() / 2),
                flate2::Compression::new(u32::from(level)),
            );
            enc.write_all(frame).expect("writing to a Vec cannot fail");
            enc.finish().expect("writing to a Vec cannot fail")
        }
    }
}

/// One episode's frames of one image channel, encoded and stored back to back (so that
/// uncompressed frames are the decoded pixels themselves, never copied frame by frame). The
/// bytes are shared, not copied, with a sink that keeps them past `write_frames` (a video
/// encoder on its own thread): an episode of 640x480 frames is hundreds of megabytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Frames {
    bytes: Arc<Vec<u8>>,
    /// Exclusive end of each frame in `bytes`.
    ends: Ends,
    /// The video packets the frames were decoded from, one per frame, when nothing changed
    /// them since (same rate, same size): a video sink may copy those instead of encoding.
    packets: Option<PacketSpan>,
    /// False when the pixels were left behind because every sink copies the packets instead
    /// ([`Frames::without_pixels`]): `bytes` is then empty, the ends are the frames'.
    pixels: bool,
}

impl Default for Frames {
    /// No frames (with all their pixels).
    fn default() -> Frames {
        Frames::raw(Vec::new(), 1)
    }
}

impl Frames {
    /// Uncompressed frames of `frame_bytes` bytes each: takes the pixels as they are.
    pub fn raw(pixels: Vec<u8>, frame_bytes: usize) -> Frames {
        let n = pixels.len() / frame_bytes.max(1);
        Frames {
            ends: Ends::new((1..=n).map(|i| (i * frame_bytes) as u64).collect()),
            bytes: Arc::new(pixels),
            packets: None,
            pixels: true,
        }
    }

    /// The same frames, noting the video packets they are the decode of.
    pub fn with_packets(mut self, packets: Option<PacketSpan>) -> Frames {
        self.packets = packets;
        self
    }

    /// The video packets the frames are the decode of, if they are.
    pub fn packets(&self) -> Option<&PacketSpan> {
        self.packets.as_ref()
    }

    /// The frames' bytes, one after another, to hand the memory on: none while a sink still
    /// shares them ([`Frames::shared`]).
    pub fn into_unshared_bytes(self) -> Option<Vec<u8>> {
        Arc::try_unwrap(self.bytes).ok()
    }

    /// Every frame back to back, shared (not copied) for as long as the caller keeps them.
    pub fn shared(&self) -> Arc<Vec<u8>> {
        Arc::clone(&self.bytes)
    }

    /// Frames of `shape` (HWC) each, encoded (in parallel when compressed).
    pub fn encode(encoding: FrameEncoding, pixels: &[u8], shape: &[usize]) -> Frames {
        use rayon::prelude::*;
        let frame_bytes = shape.iter().product::<usize>();
        if encoding == FrameEncoding::Raw {
            return Frames::raw(pixels.to_vec(), frame_bytes);
        }
        let encoded: Vec<Vec<u8>> = pixels
            .par_chunks(frame_bytes.max(1))
            .map(|f| encode_frame(encoding, f, shape))
            .collect();
        let mut bytes = Vec::with_capacity(encoded.iter().map(Vec::len).sum());
        let mut ends = Ends::default();
        for f in encoded {
            ends.push(f.len());
            bytes.extend_from_slice(&f);
        }
        Frames {
            bytes: Arc::new(bytes),
            ends,
            packets: None,
            pixels: true,
        }
    }

    pub fn len(&self) -> usize {
        self.ends.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// Frame `i`'s bytes.
    pub fn get(&self, i: usize) -> &[u8] {
        self.span(i, i + 1)
    }

    /// Frames `lo..hi`, back to back.
    pub fn span(&self, lo: usize, hi: usize) -> &[u8] {
        &self.bytes[self.ends.rows(lo..hi)]
    }

    /// Every frame, in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[u8]> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// Every frame back to back.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Exclusive end of each frame in [`Frames::bytes`].
    pub fn ends(&self) -> &[u64] {
        &self.ends
    }

    /// Frames from their bytes and ends, as [`Frames::bytes`] and [`Frames::ends`] gave them (a
    /// sharded build's partial stores them so).
    pub fn from_parts(bytes: Vec<u8>, ends: Vec<u64>) -> Frames {
        Frames {
            bytes: Arc::new(bytes),
            ends: Ends::new(ends),
            packets: None,
            pixels: true,
        }
    }

    /// The same frames without their pixels, which every sink will copy from their video
    /// packets (a shard's partial then holds where the packets are, not the frames), and the
    /// pixels' memory when nothing else shares it. Frames with no packets keep their pixels.
    pub fn without_pixels(self) -> (Frames, Option<Vec<u8>>) {
        if self.packets.is_none() {
            return (self, None);
        }
        let Frames {
            bytes,
            ends,
            packets,
            ..
        } = self;
        let stripped = Frames {
            bytes: Arc::new(Vec::new()),
            ends,
            packets,
            pixels: false,
        };
        (stripped, Arc::try_unwrap(bytes).ok())
    }

    /// Frames of these ends whose pixels were left behind ([`Frames::without_pixels`]), as a
    /// shard's partial reads them back.
    pub fn pixelless(ends: Vec<u64>, packets: PacketSpan) -> Frames {
        Frames {
            bytes: Arc::new(Vec::new()),
            ends: Ends::new(ends),
            packets: Some(packets),
            pixels: false,
        }
    }

    /// Whether the frames hold their pixels (see [`Frames::without_pixels`]).
    pub fn has_pixels(&self) -> bool {
        self.pixels
    }
}
