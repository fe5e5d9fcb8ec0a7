//! Stream copy: an episode's camera stored as the source video's own packets, not encoded again
//! (hdf5's `image_compression = "video"`, `video_copy`).
//!
//! When an episode's rows are a video file's own frames one by one (the source read them at its
//! rate, and nothing resized them: [`PacketSpan`]), the packets of those frames are the episode's
//! video already. Copying them costs no encoder time, adds no second generation of compression
//! loss, and keeps the source's size. They are copied only when the copy decodes on its own to
//! exactly the frames the rows hold, and is as quick to seek as an encoded file:
//!
//! - the packets of the span are consecutive in decode order (no other frame's packet among them,
//!   as with B-frames that reach across the episode's boundary);
//! - the first of them is a keyframe, and it is the first frame shown;
//! - frame `i` is shown at `i / fps` from the first (the loader finds frames by time);
//! - keyframes are at most `gop` frames apart, the profile's random-access bound.
//!
//! Otherwise the episode is encoded as any other ([`CopyOutcome::Refused`] says why). Times are shifted
//! so that the first frame is shown at 0, in the source's time base; the container is written
//! with libavformat's `bitexact` flag, so the bytes depend only on the source's packets.

use std::path::Path;

#[cfg(not(feature = "video"))]
use crate::error::Error;
use crate::error::Result;
use crate::source::video::PacketSpan;

/// Codecs whose packets are copied when the spec names no `video_codec`: those an mp4 holds and
/// PyAV's wheels decode.
pub const COPIED_CODECS: [&str; 5] = ["h264", "hevc", "av1", "vp9", "mpeg4"];

/// What became of a copy.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CopyOutcome {
    /// The file holds the span's packets: this many frames, in the source stream's format.
    Copied {
        frames: u64,
        format: crate::sink::video_info::StreamFormat,
    },
    /// The span's packets cannot stand alone as the episode's video (the sentence says why);
    /// nothing was written.
    Refused(String),
}

/// Copies the packets of `span` into a new mp4 at `out`, or refuses (see the module's rules).
/// An error is a file that cannot be read or written.
pub fn copy(span: &PacketSpan, out: &Path, fps: f64, gop: u32) -> Result<CopyOutcome> {
    #[cfg(feature = "video")]
    {
        imp::copy(span, out, fps, gop)
    }
    #[cfg(not(feature = "video"))]
    {
        let _ = (span, fps, gop);
        Err(Error::output(format!(
            "{}: writing video needs a chunkc built with the `video` cargo feature",
            out.display()
        )))
    }
}

/// Whether [`copy`] would copy `span` (its packets are read, nothing is written): `None`, or
/// the sentence saying why not.
pub fn check(span: &PacketSpan, fps: f64, gop: u32) -> Result<Option<String>> {
    #[cfg(feature = "video")]
    {
        imp::check(span, fps, gop)
    }
    #[cfg(not(feature = "video"))]
    {
        let _ = (span, fps, gop);
        Ok(Some(
            "this chunkc was built without the `video` cargo feature".into(),
        ))
    }
}

/// The checks on the span's packets, apart from FFmpeg: per packet in decode order, its
/// presentation time in ticks and whether it is a keyframe. `ticks_per_frame` is one frame's
/// duration in the stream's time base.
pub fn refusal(packets: &[(i64, bool)], ticks_per_frame: f64, gop: u32) -> Option<String> {
    let Some(&(first, key)) = packets.first() else {
        return Some("the episode has no packets".into());
    };
    if !key {
        return Some("the episode does not start on a keyframe".into());
    }
    let mut shown: Vec<(i64, bool)> = packets.to_vec();
    shown.sort_by_key(|&(pts, _)| pts);
    if shown[0].0 != first {
        return Some("a frame shown before the first keyframe needs an earlier one".into());
    }
    for (i, &(pts, _)) in shown.iter().enumerate() {
        let at = ((pts - first) as f64 / ticks_per_frame).round();
        if at != i as f64 {
            return Some(format!(
                "frame {i} is shown at frame time {at}: the video's frames are not 1/fps apart"
            ));
        }
    }
    let keys: Vec<usize> = (0..shown.len()).filter(|&i| shown[i].1).collect();
    let longest = keys
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(keys.last().map(|&k| shown.len() - k))
        .max()
        .unwrap_or(0);
    (longest > gop as usize)
        .then(|| format!("keyframes {longest} frames apart, more than `video_gop` = {gop} (set `video_gop = {longest}`, or leave it unset to keep the source's keyframes)"))
}

#[cfg(feature = "video")]
mod imp {
    //! The FFmpeg side: demux the span's packets, check them, mux them into a new mp4.

    use std::path::Path;

    use ff::{codec, encoder, format, packet::Ref as _, Dictionary, Packet, Rational};
    use ffmpeg_next as ff;

    use super::{refusal, CopyOutcome};
    use crate::error::{Error, Result};
    use crate::source::video::PacketSpan;

    /// The span's packets, with the stream's time base and parameters, or why they cannot
    /// stand alone as the episode's video.
    struct Picked {
        packets: Vec<Packet>,
        time_base: Rational,
        params: codec::Parameters,
    }

    fn pick(span: &PacketSpan, fps: f64, gop: u32) -> Result<std::result::Result<Picked, String>> {
        let _ = ff::init();
        let source = |m: String| Error::source(format!("{}: {m}", span.file.display()));
        let mut ictx = format::input(&span.file)
            .map_err(|e| source(format!("cannot open the video to copy it: {e}")))?;
        let (index, time_base, params) = {
            let ist = ictx
                .streams()
                .best(ff::media::Type::Video)
                .ok_or_else(|| source("the file holds no video stream".into()))?;
            (ist.index(), ist.time_base(), ist.parameters())
        };
        let tick = f64::from(time_base.numerator()) / f64::from(time_base.denominator());
        // The span's frames, with half a frame either side.
        let margin = 0.5 / fps;
        // Reading starts at the keyframe before the span, not at the file's start (a v3.0 file
        // holds many episodes: reading every earlier episode's packets made copies quadratic).
        if span.first - margin > 0.0 {
            let tb = (time_base.numerator(), time_base.denominator());
            crate::source::video::seek_back(&mut ictx, index, tb, span.first - margin)
                .map_err(|e| source(format!("cannot seek to the packets to copy: {e}")))?;
        }
        let inside = |t: f64| t >= span.first - margin && t <= span.last + margin;
        let mut picked: Vec<Packet> = Vec::with_capacity(span.frames);
        while picked.len() < span.frames {
            let mut packet = Packet::empty();
            match packet.read(&mut ictx) {
                Ok(()) => {}
                Err(ff::Error::Eof) => break,
                Err(e) => return Err(source(format!("reading packets to copy failed: {e}"))),
            }
            if packet.stream() != index {
                continue;
            }
            let discarded = unsafe { (*packet.as_ptr()).flags & ff::ffi::AV_PKT_FLAG_DISCARD != 0 };
            let pts = packet.pts();
            let shown = pts.is_some_and(|p| inside(p as f64 * tick));
            match (shown, picked.is_empty()) {
                (true, _) if discarded => {
                    return Ok(Err("the file's edit list hides some frames".into()))
                }
                (true, _) => picked.push(packet),
                (false, true) => {}
                (false, false) => {
                    return Ok(Err(
                        "another episode's packet lies among this episode's (decode order)".into(),
                    ))
                }
            }
        }
        if picked.len() != span.frames {
            let why = format!("{} packets for {} frames", picked.len(), span.frames);
            return Ok(Err(why));
        }
        let times: Vec<(i64, bool)> = picked
            .iter()
            .map(|p| (p.pts().unwrap_or(0), p.is_key()))
            .collect();
        if let Some(why) = refusal(&times, 1.0 / (fps * tick), gop) {
            return Ok(Err(why));
        }
        Ok(Ok(Picked {
            packets: picked,
            time_base,
            params,
        }))
    }

    pub fn check(span: &PacketSpan, fps: f64, gop: u32) -> Result<Option<String>> {
        Ok(pick(span, fps, gop)?.err())
    }

    pub fn copy(span: &PacketSpan, out: &Path, fps: f64, gop: u32) -> Result<CopyOutcome> {
        let Picked {
            packets,
            time_base,
            params,
        } = match pick(span, fps, gop)? {
            Ok(picked) => picked,
            Err(why) => return Ok(CopyOutcome::Refused(why)),
        };
        let shift = packets[0].pts().unwrap_or(0);
        let format = crate::sink::video_info::of_parameters(&params);

        let fail = |m: String| Error::output(format!("{}: {m}", out.display()));
        let mut octx = format::output_as(out, "mp4")
            .map_err(|e| fail(format!("cannot create the mp4: {e}")))?;
        {
            let mut ost = octx
                .add_stream(encoder::find(codec::Id::None))
                .map_err(|e| fail(format!("cannot add the stream: {e}")))?;
            ost.set_parameters(params);
            // The mp4 muxer picks the sample entry's tag for the codec itself.
            unsafe { (*ost.parameters().as_mut_ptr()).codec_tag = 0 };
            ost.set_time_base(time_base);
            let rate = Rational::from(fps);
            ost.set_rate(rate);
            ost.set_avg_frame_rate(rate);
        }
        let mut header = Dictionary::new();
        header.set("fflags", "+bitexact");
        header.set("movflags", "+faststart");
        octx.write_header_with(header)
            .map_err(|e| fail(format!("cannot write the mp4 header: {e}")))?;
        let stream_time_base = octx.stream(0).expect("added").time_base();
        for mut packet in packets {
            packet.set_stream(0);
            packet.set_pts(packet.pts().map(|p| p - shift));
            packet.set_dts(packet.dts().map(|d| d - shift));
            packet.set_position(-1);
            packet.rescale_ts(time_base, stream_time_base);
            packet
                .write_interleaved(&mut octx)
                .map_err(|e| fail(format!("writing a copied packet: {e}")))?;
        }
        octx.write_trailer()
            .map_err(|e| fail(format!("writing the mp4 index: {e}")))?;
        Ok(CopyOutcome::Copied {
            frames: span.frames as u64,
            format,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::refusal;

    /// Frames 512 ticks apart, keyframes where `keys` says.
    fn stream(pts: &[i64], keys: &[bool]) -> Vec<(i64, bool)> {
        pts.iter().zip(keys).map(|(&p, &k)| (p * 512, k)).collect()
    }

    #[test]
    fn whole_gops_on_the_grid_are_copied() {
        let s = stream(&[10, 11, 12, 13], &[true, false, true, false]);
        assert_eq!(refusal(&s, 512.0, 2), None);
        // B-frames: decode order 0 2 1 3, shown 0 1 2 3.
        let b = stream(&[10, 12, 11, 13], &[true, false, false, false]);
        assert_eq!(refusal(&b, 512.0, 4), None);
    }

    #[test]
    fn what_cannot_stand_alone_is_refused() {
        let mid = stream(&[10, 11], &[false, true]);
        assert!(refusal(&mid, 512.0, 8).unwrap().contains("keyframe"));
        // A leading B-frame shown before the keyframe.
        let open = stream(&[11, 10, 12], &[true, false, false]);
        assert!(refusal(&open, 512.0, 8).unwrap().contains("earlier"));
        let gap = stream(&[10, 11, 13], &[true, false, false]);
        assert!(refusal(&gap, 512.0, 8).unwrap().contains("1/fps"));
        let long = stream(&[10, 11, 12, 13, 14], &[true, false, false, false, false]);
        assert!(refusal(&long, 512.0, 4).unwrap().contains("video_gop"));
        assert!(refusal(&[], 512.0, 4).is_some());
    }
}
