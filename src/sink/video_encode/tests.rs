//! The encoder's tests: determinism, odd sizes, abandoned streams, the codecs a build has.
use super::*;
use crate::spec::VideoCodec;

fn settings() -> VideoSettings {
    VideoSettings {
        codec: VideoCodec::Libsvtav1,
        crf: 30,
        gop: 2,
        copy: crate::spec::StreamCopy::Never,
        copy_gop: None,
        closed_gop: false,
    }
}

/// The frame size and rate most of these tests encode.
const SMALL: StreamShape = StreamShape {
    height: 64,
    width: 96,
    fps: 10.0,
};

fn write(path: &Path, n: usize) -> u64 {
    let shape = SMALL;
    let mut s = VideoStream::create(path, shape, settings()).unwrap();
    for i in 0..n {
        let frame: Vec<u8> = (0..64 * 96 * 3)
            .map(|p| ((p / 3 % 96 + i * 4) % 256) as u8)
            .collect();
        s.push(&frame).unwrap();
    }
    s.finish().unwrap()
}

/// Frames converted to yuv420p before the stream (in parallel blocks, as a waiting encoder
/// holds them) encode to the same bytes as the RGB24 frames pushed one by one; and the planes
/// are those of an independent BT.601 limited-range conversion, within swscale's rounding.
#[cfg(feature = "video")]
#[test]
fn frames_converted_first_give_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let shape = SMALL;
    let n = 37; // more than two of the conversion's blocks, the last one short
    let frames: Vec<u8> = (0..n)
        .flat_map(|i| {
            (0..64 * 96 * 3).map(move |p| ((p / 3 % 96 + i * 4 + p % 3 * 50) % 256) as u8)
        })
        .collect();
    let (a, b) = (dir.path().join("a.mp4"), dir.path().join("b.mp4"));
    let mut s = VideoStream::create(&a, shape, settings()).unwrap();
    s.push_all(&frames).unwrap();
    assert_eq!(s.finish().unwrap(), n as u64);
    let yuv = Yuv420p::of(&frames, shape).unwrap();
    assert_eq!(yuv.planes.len(), n * 64 * 96 * 3 / 2);
    let mut s = VideoStream::create(&b, shape, settings()).unwrap();
    s.push_yuv(&yuv).unwrap();
    assert_eq!(s.finish().unwrap(), n as u64);
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
    // Luma of the last frame's first pixel: 16 + 219 * (0.299 R + 0.587 G + 0.114 B) / 255.
    let last = (n - 1) * 64 * 96 * 3;
    let (r, g, bl) = (
        frames[last] as f64,
        frames[last + 1] as f64,
        frames[last + 2] as f64,
    );
    let y = 16.0 + 219.0 * (0.299 * r + 0.587 * g + 0.114 * bl) / 255.0;
    let got = yuv.planes[(n - 1) * 64 * 96 * 3 / 2] as f64;
    assert!((got - y).abs() <= 1.5, "Y {got}, expected {y:.1}");
}

/// The format a stream says it holds, from its encoder's configuration, is what FFmpeg's
/// demuxer and decoder read back from the file (AV1 and H.264, whose extradata the encoders
/// leave as a raw sequence header and as Annex B).
#[cfg(feature = "video")]
#[test]
fn the_encoders_format_is_what_the_file_holds() {
    let dir = tempfile::tempdir().unwrap();
    let shape = SMALL;
    let codecs = [VideoCodec::Libsvtav1, VideoCodec::Libx264];
    for codec in codecs
        .into_iter()
        .filter(|&c| ffmpeg_next::encoder::find_by_name(c.name()).is_some())
    {
        let path = dir.path().join(format!("{}.mp4", codec.name()));
        let mut s = VideoStream::create(
            &path,
            shape,
            VideoSettings {
                codec,
                crf: 30,
                ..settings()
            },
        )
        .unwrap();
        s.push_all(&vec![77u8; 64 * 96 * 3 * 4]).unwrap();
        let said = s.format().unwrap();
        s.finish().unwrap();
        let read = crate::sink::video_info::stream_format(&path).unwrap();
        assert_eq!(said, read, "{}", codec.name());
        assert!(said.profile.is_some(), "{}: no profile", codec.name());
    }
}

#[test]
fn the_same_frames_give_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.mp4"), dir.path().join("b.mp4"));
    assert_eq!(write(&a, 7), 7);
    // In the background, while another stream is written here.
    let mut bg = Background::spawn(&b, SMALL, settings()).unwrap();
    let frames: Vec<u8> = (0..7)
        .flat_map(|i| (0..64 * 96 * 3).map(move |p| ((p / 3 % 96 + i * 4) % 256) as u8))
        .collect();
    bg.push(std::sync::Arc::new(frames)).unwrap();
    write(&dir.path().join("c.mp4"), 3);
    assert_eq!(bg.finish().unwrap(), 7);
    let (a, b) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    assert!(a.len() > 100);
    assert!(a == b, "two encodes of the same frames differ");
    // No library version in the container.
    assert!(!a.windows(4).any(|w| w == b"Lavf"));
}

/// hdf5 `video` storage's encoder, on frames with detail and motion.
fn x264_file(path: &Path, asm: Option<&str>) -> Vec<u8> {
    let shape = StreamShape {
        height: 64,
        width: 96,
        fps: 50.0,
    };
    let settings = crate::spec::STORAGE_VIDEO;
    let mut s = match asm {
        None => VideoStream::create(path, shape, settings),
        Some(asm) => VideoStream::create_with_asm(path, shape, settings, asm),
    }
    .unwrap();
    let mut state = 1u64;
    for i in 0..38 {
        let frame: Vec<u8> = (0..64 * 96 * 3)
            .map(|p| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((p / 3 % 96) * 3 + i * 5 + (state >> 60) as usize) as u8
            })
            .collect();
        s.push(&frame).unwrap();
    }
    s.finish().unwrap();
    std::fs::read(path).unwrap()
}

#[test]
fn x264_bytes_do_not_depend_on_what_the_heap_held() {
    // Each encode runs on a new thread whose heap was first filled with other bytes and
    // freed. x264's AVX-512 code used to read such leftovers (2 to 4 distinct files of 32).
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<Vec<u8>> = (0..32u8)
        .map(|k| {
            let path = dir.path().join(format!("{k}.mp4"));
            std::thread::spawn(move || {
                let dirt: Vec<Vec<u8>> = (0..4000)
                    .map(|i| vec![k.wrapping_mul(37).wrapping_add(i as u8); 16 + i * 37 % 20000])
                    .collect();
                drop(dirt);
                x264_file(&path, None)
            })
            .join()
            .unwrap()
        })
        .collect();
    let distinct: std::collections::BTreeSet<&Vec<u8>> = files.iter().collect();
    assert_eq!(
        distinct.len(),
        1,
        "{} different files of 32",
        distinct.len()
    );
}

#[test]
fn x264_bytes_do_not_depend_on_the_cpu() {
    // What this machine runs, a machine without AVX-512, and x264's C code alone.
    let dir = tempfile::tempdir().unwrap();
    let native = x264_file(&dir.path().join("native.mp4"), None);
    let avx2 = "MMX2,SSE,SSE2,SSE2Fast,LZCNT,SSE3,SSSE3,SSE4.1,SSE4.2,AVX,FMA3,BMI1,BMI2,AVX2";
    for asm in [avx2, "0"] {
        let other = x264_file(&dir.path().join("other.mp4"), Some(asm));
        assert!(other == native, "x264 limited to `{asm}` wrote other bytes");
    }
}

#[test]
fn a_stream_dropped_unfinished_is_abandoned_not_flushed() {
    // A build that fails elsewhere drops its encoders; SVT-AV1 1.4 hung in the flush of an
    // encoder that had been sent no frame (and so did the failed build).
    let dir = tempfile::tempdir().unwrap();
    let shape = SMALL;
    let start = std::time::Instant::now();
    drop(Background::spawn(&dir.path().join("none.mp4"), shape, settings()).unwrap());
    let mut some = Background::spawn(&dir.path().join("some.mp4"), shape, settings()).unwrap();
    some.push(std::sync::Arc::new(vec![9u8; 64 * 96 * 3 * 3]))
        .unwrap();
    drop(some);
    assert!(start.elapsed() < std::time::Duration::from_secs(20));
}

#[test]
fn mpeg4_encodes_what_svtav1_refuses() {
    // The LeRobot exports' codec for a camera under 64 pixels in a build without x264.
    let dir = tempfile::tempdir().unwrap();
    let shape = StreamShape {
        height: 32,
        width: 32,
        fps: 10.0,
    };
    let mpeg4 = VideoSettings {
        codec: VideoCodec::Mpeg4,
        crf: 3,
        gop: 2,
        ..settings()
    };
    let write = |name: &str| {
        let path = dir.path().join(name);
        let mut s = VideoStream::create(&path, shape, mpeg4).unwrap();
        for i in 0..5u8 {
            s.push(&vec![i * 40; 32 * 32 * 3]).unwrap();
        }
        assert_eq!(s.finish().unwrap(), 5);
        std::fs::read(path).unwrap()
    };
    let (a, b) = (write("a.mp4"), write("b.mp4"));
    assert!(a.len() > 100 && a == b);
    assert!(
        !a.windows(4).any(|w| w == b"Lavc"),
        "no encoder version in the stream"
    );
    let small = VideoStream::create(&dir.path().join("svt.mp4"), shape, settings());
    assert!(small.is_err(), "SVT-AV1 1.4 refuses 32x32 frames");
}

#[test]
fn odd_sizes_are_refused_with_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("odd.mp4");
    let shape = StreamShape {
        height: 63,
        width: 96,
        fps: 10.0,
    };
    let err = VideoStream::create(&path, shape, settings())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("odd.mp4") && err.contains("even"), "{err}");
}
