use std::path::{Path, PathBuf};

use super::*;
use crate::exec::process::Prepared;
use crate::exec::rate::Partial;
use crate::sink::Frames;
use crate::source::video::{PacketSpan, Probe};
use crate::stats::{ImagePartial, Moments};

fn span() -> PacketSpan {
    PacketSpan {
        file: "/data/videos/file-000.mp4".into(),
        probe: Probe {
            codec: "av1".into(),
            width: 2,
            height: 2,
        },
        first: 0.1,
        last: 0.2,
        frames: 2,
    }
}

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
                    Frames::raw(vec![7u8; 24], 12).with_packets(Some(span())),
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
fn frames_left_to_their_packets_keep_ends_and_packets_only() {
    let dir = tempfile::tempdir().unwrap();
    let frames = || Frames::raw(vec![7u8; 24 * 1000], 12 * 1000).with_packets(Some(span()));
    let pixels = frames();
    // Shared pixels stay with their other holder; unshared ones come back to be reused.
    assert!(pixels.clone().without_pixels().1.is_none());
    let (stripped, freed) = frames().without_pixels();
    assert_eq!(freed.map(|b| b.len()), Some(24 * 1000));
    assert!(!stripped.has_pixels() && stripped.len() == 2);
    let record = |frames: Frames| {
        Record::Kept(Processed {
            data: vec![vec![Prepared::Frames(vec![(FrameEncoding::Raw, frames)])]],
            partials: vec![vec![None]],
        })
    };
    let full = written(dir.path(), &[record(pixels)]);
    let full_bytes = std::fs::metadata(&full).unwrap().len();
    let path = written(dir.path(), &[record(stripped.clone())]);
    assert!(std::fs::metadata(&path).unwrap().len() + 24 * 1000 <= full_bytes);
    verify(&path).unwrap();
    let Record::Kept(p) = Reader::open(&path).unwrap().record().unwrap() else {
        panic!("kept")
    };
    match &p.data[0][0] {
        Prepared::Frames(got) => {
            assert_eq!(got, &vec![(FrameEncoding::Raw, stripped)]);
            assert!(!got[0].1.has_pixels() && got[0].1.packets() == Some(&span()));
        }
        _ => panic!("frames"),
    }
    // Frames without packets keep their pixels.
    let (kept, none) = Frames::raw(vec![1u8; 24], 12).without_pixels();
    assert!(kept.has_pixels() && none.is_none() && kept.bytes().len() == 24);
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
