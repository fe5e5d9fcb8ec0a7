//! Which frames of a video file an episode's camera is, when they are the file's own frames one
//! per row: what a sink needs to copy the file's packets instead of decoding and encoding them
//! again (`image_compression = "video"`, see `sink::video_copy`).

use std::path::PathBuf;

use super::Probe;

/// The frames of one file that rows `0..frames` of an episode took, in order and without a gap
/// or a repeat: the file's frames `first..=last` in presentation order.
#[derive(Debug, Clone, PartialEq)]
pub struct PacketSpan {
    /// The file, as the source opened it.
    pub file: PathBuf,
    /// The stream as its header describes it (codec, width, height).
    pub probe: Probe,
    /// Presentation times (seconds, `pts × time_base` as the demuxer gives them) of the first
    /// and the last frame.
    pub first: f64,
    pub last: f64,
    /// How many frames (= the episode's rows).
    pub frames: usize,
}

/// When every row's frame (`picks`: per row, the index of its frame among the file's frames in
/// presentation order) is the one after the previous row's, the first and last frame's indices.
/// A repeated frame (a row short of frames), a skipped one (the rows sample the stream) or a
/// row without a frame gives `None`.
pub fn consecutive(picks: &[Option<usize>]) -> Option<(usize, usize)> {
    let first = (*picks.first()?)?;
    for (k, pick) in picks.iter().enumerate() {
        if *pick != Some(first + k) {
            return None;
        }
    }
    Some((first, first + picks.len() - 1))
}

#[cfg(test)]
mod tests {
    use super::consecutive;

    #[test]
    fn only_one_frame_per_row_in_order() {
        assert_eq!(consecutive(&[Some(4), Some(5), Some(6)]), Some((4, 6)));
        assert_eq!(consecutive(&[Some(0)]), Some((0, 0)));
        assert_eq!(consecutive(&[]), None);
        // A frame used twice, one skipped, or a row without a frame.
        assert_eq!(consecutive(&[Some(4), Some(4), Some(5)]), None);
        assert_eq!(consecutive(&[Some(4), Some(6), Some(7)]), None);
        assert_eq!(consecutive(&[Some(4), None]), None);
    }
}
