//! The parallel part of reading an episode: its channels converted to every output rate, its
//! frames encoded once per encoding a sink asked for, and, for a training episode, its
//! statistics partials. Nothing here writes; the results are consumed in episode order.

use super::rate::Partial;
use crate::plan::Conversion;
use crate::recycle;
use crate::resize::Resize;
use crate::sink::{FrameEncoding, Frames};
use crate::source::video::PacketSpan;
use crate::source::{ChannelData, Episode, Source};
use crate::stats::{self, ImagePartial};

/// How one rate's episodes are prepared.
pub(super) struct Job {
    pub conversion: Conversion,
    /// The frame encodings its sinks use, each once.
    pub encodings: Vec<FrameEncoding>,
    /// Per channel (manifest order): the resize of a camera stored resized
    /// (`[profiles.<name>.cameras.<channel>]`), applied before anything else sees the frames.
    pub resize: Vec<Option<Resize>>,
}

/// One episode's channel after the parallel part of the work.
pub(super) enum Prepared {
    Lowdim(Vec<f32>),
    /// The frames in every encoding a sink at this rate asked for.
    Frames(Vec<(FrameEncoding, Frames)>),
}

/// One episode after the parallel part of the work: decimated per rate, images compressed,
/// statistics partials computed.
pub(super) struct Processed {
    /// Per rate (in `RateState` order), per channel.
    pub data: Vec<Vec<Prepared>>,
    /// Per rate, per channel: the statistics partial, if this is a training episode.
    pub partials: Vec<Vec<Option<Partial>>>,
}

/// Decimates an episode (read unpadded: [`Source::read_unpadded`]) to every rate, resizes the
/// cameras a rate stores resized, encodes its frames for every sink, and computes the
/// statistics partials of a training episode (of the frames as stored). Runs in parallel over
/// episodes.
pub(super) fn process(
    mut episode: Episode,
    source: &dyn Source,
    rates: &[Job],
    train: bool,
) -> Processed {
    let manifest = source.manifest();
    let channels = &manifest.channels;
    let mut data: Vec<Vec<Prepared>> = rates.iter().map(|_| Vec::new()).collect();
    let mut partials: Vec<Vec<Option<Partial>>> = rates.iter().map(|_| Vec::new()).collect();
    // The source's own rate goes last, so that it can take the values once every other rate
    // has been derived from them (no copy of the episode).
    let identity = |r: &usize| rates[*r].conversion == Conversion::Decimate { factor: 1 };
    let order: Vec<usize> = (0..rates.len())
        .filter(|r| !identity(r))
        .chain((0..rates.len()).filter(identity))
        .collect();
    for (k, &r) in order.iter().enumerate() {
        let Job {
            conversion,
            encodings,
            resize,
        } = &rates[r];
        let last = k + 1 == order.len();
        let mut per_channel = Vec::with_capacity(channels.len());
        let mut per_partial = Vec::with_capacity(channels.len());
        let channel_data = channels.iter().zip(episode.channels.iter_mut()).zip(resize);
        for (c, ((ch, values), resize)) in channel_data.enumerate() {
            // A mixture source's low-dim rows come at its own width (`read_unpadded`).
            let width = match values {
                ChannelData::Lowdim(_) => manifest.own_width(c, episode.id),
                ChannelData::Image(_) => ch.width(),
            };
            let converted = match *conversion {
                // The source's own rate, last, takes the values (no copy).
                Conversion::Decimate { factor: 1 } if last => match values {
                    ChannelData::Lowdim(v) => ChannelData::Lowdim(std::mem::take(v)),
                    ChannelData::Image(v) => ChannelData::Image(std::mem::take(v)),
                },
                // A mixture source without the channel: nothing but padding.
                _ if width == 0 => ChannelData::Lowdim(Vec::new()),
                _ => conversion.apply(values, width, episode.len),
            };
            match converted {
                ChannelData::Lowdim(v) => {
                    // At the channel's width: a mixture's padding counts as zeros.
                    let rows = conversion.len(episode.len);
                    let moments = || stats::Moments::of_narrow_rows(&v, rows, ch.width());
                    per_partial.push(train.then(|| Partial::Lowdim(moments())));
                    per_channel.push(Prepared::Lowdim(v));
                }
                ChannelData::Image(d) => {
                    // The frames are still the video's own only at the source's rate and size.
                    let same =
                        *conversion == Conversion::Decimate { factor: 1 } && resize.is_none();
                    let packets = episode.packets.remove(&c).filter(|_| same);
                    let (d, shape) = match resize {
                        Some(resize) => {
                            let resized = resize.frames(&d);
                            // The source's frames' memory takes the next episode's decode.
                            recycle::give(d);
                            (resized, resize.shape().to_vec())
                        }
                        None => (d, ch.shape.clone()),
                    };
                    let (frames, partial) = prepare_frames(d, &shape, encodings, train, packets);
                    per_partial.push(partial);
                    per_channel.push(frames);
                }
            }
        }
        data[r] = per_channel;
        partials[r] = per_partial;
    }
    Processed { data, partials }
}

/// One camera's frames as stored (per-step `shape`): their statistics partial (a training
/// episode's), and the frames in every encoding of `encodings`, each noting the video `packets`
/// they are the decode of, if they are.
fn prepare_frames(
    d: Vec<u8>,
    shape: &[usize],
    encodings: &[FrameEncoding],
    train: bool,
    packets: Option<PacketSpan>,
) -> (Prepared, Option<Partial>) {
    let width = shape.iter().product::<usize>();
    let frames = d.len() / width.max(1);
    let colors = *shape.last().unwrap_or(&1);
    let partial = train.then(|| Partial::Image(ImagePartial::of_frames(&d, frames, colors)));
    // Compressed encodings first, then the pixels themselves become the raw frames.
    let mut encoded: Vec<(FrameEncoding, Frames)> = encodings
        .iter()
        .filter(|&&enc| enc != FrameEncoding::Raw)
        .map(|&enc| {
            let frames = Frames::encode(enc, &d, shape).with_packets(packets.clone());
            (enc, frames)
        })
        .collect();
    if encodings.contains(&FrameEncoding::Raw) {
        encoded.push((
            FrameEncoding::Raw,
            Frames::raw(d, width).with_packets(packets),
        ));
    }
    (Prepared::Frames(encoded), partial)
}
