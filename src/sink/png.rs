//! PNG encoding of image frames, as LeRobot stores them in parquet (`{bytes, path}` structs).
//!
//! Deterministic: filter type 0 on every row and zlib at a fixed level, so the same pixels always
//! give the same bytes. Frames are encoded in `exec`'s parallel frame stage
//! ([`super::FrameEncoding::Png`]), never inside the sink.

use std::io::Write;

/// zlib level of the image data (PIL's default for PNG).
const LEVEL: u32 = 6;

/// A PNG of one `u8` frame of `shape` (HWC, HW, or anything else as one row of gray pixels).
pub fn encode(frame: &[u8], shape: &[usize]) -> Vec<u8> {
    let (h, w, c) = match shape {
        [h, w, c] => (*h, *w, *c),
        [h, w] => (*h, *w, 1),
        _ => (1, frame.len(), 1),
    };
    let color: u8 = match c {
        1 => 0,
        2 => 4,
        3 => 2,
        _ => 6,
    };
    let mut raw = Vec::with_capacity(h * (w * c + 1));
    for row in frame.chunks((w * c).max(1)) {
        raw.push(0);
        raw.extend_from_slice(row);
    }
    let mut z = flate2::write::ZlibEncoder::new(
        Vec::with_capacity(raw.len() / 2),
        flate2::Compression::new(LEVEL),
    );
    z.write_all(&raw).expect("writing to a Vec cannot fail");
    let idat = z.finish().expect("writing to a Vec cannot fail");
    let mut out = Vec::with_capacity(idat.len() + 64);
    out.extend_from_slice(b"\x89PNG\r\n\x1a\n");
    let mut chunk = |kind: &[u8], data: &[u8]| {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(data);
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        out.extend_from_slice(&crc.sum().to_be_bytes());
    };
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&(w as u32).to_be_bytes());
    ihdr.extend_from_slice(&(h as u32).to_be_bytes());
    ihdr.extend_from_slice(&[8, color, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &idat);
    chunk(b"IEND", &[]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// The chunks of a PNG stream: (kind, data), checking each CRC.
    fn chunks(png: &[u8]) -> Vec<(Vec<u8>, Vec<u8>)> {
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let mut out = Vec::new();
        let mut at = 8;
        while at < png.len() {
            let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
            let kind = &png[at + 4..at + 8];
            let data = &png[at + 8..at + 8 + len];
            let crc = u32::from_be_bytes(png[at + 8 + len..at + 12 + len].try_into().unwrap());
            let mut want = flate2::Crc::new();
            want.update(kind);
            want.update(data);
            assert_eq!(
                crc,
                want.sum(),
                "CRC of {:?}",
                String::from_utf8_lossy(kind)
            );
            out.push((kind.to_vec(), data.to_vec()));
            at += 12 + len;
        }
        out
    }

    #[test]
    fn rows_come_back_after_their_filter_byte() {
        let (h, w, c) = (5usize, 7usize, 3usize);
        let frame: Vec<u8> = (0..h * w * c).map(|i| (i * 37 % 256) as u8).collect();
        let png = encode(&frame, &[h, w, c]);
        let parts = chunks(&png);
        let kinds: Vec<&[u8]> = parts.iter().map(|(k, _)| k.as_slice()).collect();
        assert_eq!(kinds, [&b"IHDR"[..], b"IDAT", b"IEND"]);
        let ihdr = &parts[0].1;
        assert_eq!(u32::from_be_bytes(ihdr[0..4].try_into().unwrap()), w as u32);
        assert_eq!(u32::from_be_bytes(ihdr[4..8].try_into().unwrap()), h as u32);
        assert_eq!(&ihdr[8..], &[8, 2, 0, 0, 0]);
        let mut raw = Vec::new();
        flate2::read::ZlibDecoder::new(parts[1].1.as_slice())
            .read_to_end(&mut raw)
            .unwrap();
        assert_eq!(raw.len(), h * (w * c + 1));
        for (r, row) in raw.chunks(w * c + 1).enumerate() {
            assert_eq!(row[0], 0, "filter of row {r}");
            assert_eq!(&row[1..], &frame[r * w * c..(r + 1) * w * c]);
        }
        // Gray frames are color type 0.
        assert_eq!(chunks(&encode(&frame[..h * w], &[h, w]))[0].1[9], 0);
    }
}
