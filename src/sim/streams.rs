//! Counter-based random streams.
//!
//! A run's seed is expanded into one ChaCha key; every draw comes from a
//! stream selected by what it is for (the run's calibration errors, one
//! viewpoint's arm error, one block of beams). Streams are independent of each
//! other and of the order in which threads reach them, so results are
//! identical whatever the thread count.

use rand::SeedableRng;
use rand_chacha::ChaCha12Rng;

/// Beams per random stream: beams are simulated in blocks of this size, each
/// block with its own stream.
pub const BEAM_BLOCK: usize = 1024;

/// What a stream is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stream {
    /// Errors shared by the whole run: T_sw and T_cr.
    Run,
    /// Errors of one viewpoint: T_rw (or its joint errors).
    Viewpoint(u32),
    /// Per-beam errors of one block of beams of one viewpoint.
    Beams {
        /// The viewpoint's index.
        viewpoint: u32,
        /// The block's index within the viewpoint's beams.
        block: u32,
    },
    /// The range scale error of one viewpoint's frame
    /// ([`RangeModel::scale_sigma`](crate::uncertainty::RangeModel)).
    FrameScale(u32),
    /// The sub-voxel offset of the map's grid (evaluation, not an error).
    GridOffset,
    /// The registration errors the reference `registration_belief` blurs
    /// the registered truth over (evaluation, not an error of the scans).
    RegistrationBelief,
}

impl Stream {
    fn id(self) -> u64 {
        match self {
            Stream::Run => 0,
            Stream::Viewpoint(v) => (1 << 62) | v as u64,
            Stream::Beams { viewpoint, block } => {
                (2 << 62) | ((viewpoint as u64) << 32) | block as u64
            }
            Stream::GridOffset => 3 << 62,
            Stream::RegistrationBelief => (3 << 62) | 1,
            Stream::FrameScale(v) => (3 << 62) | (1 << 32) | v as u64,
        }
    }
}

/// The streams of one run.
#[derive(Clone, Debug)]
pub struct Streams {
    key: [u8; 32],
}

impl Streams {
    /// The streams of the run with this seed.
    pub fn new(seed: u64) -> Self {
        // SplitMix64 expansion of the seed into a 256-bit key.
        let mut state = seed;
        let mut key = [0u8; 32];
        for chunk in key.chunks_exact_mut(8) {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            chunk.copy_from_slice(&(z ^ (z >> 31)).to_le_bytes());
        }
        Self { key }
    }

    /// A fresh generator positioned at the start of `stream`.
    pub fn rng(&self, stream: Stream) -> ChaCha12Rng {
        let mut rng = ChaCha12Rng::from_seed(self.key);
        rng.set_stream(stream.id());
        rng
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a = Streams::new(42);
        let b = Streams::new(42);
        let draw = |s: &Streams, st| -> Vec<u64> {
            let mut r = s.rng(st);
            (0..4).map(|_| r.random()).collect()
        };
        assert_eq!(draw(&a, Stream::Run), draw(&b, Stream::Run));
        assert_ne!(draw(&a, Stream::Run), draw(&a, Stream::Viewpoint(0)));
        assert_ne!(
            draw(&a, Stream::Viewpoint(1)),
            draw(&a, Stream::Viewpoint(0))
        );
        assert_ne!(
            draw(
                &a,
                Stream::Beams {
                    viewpoint: 0,
                    block: 1
                }
            ),
            draw(
                &a,
                Stream::Beams {
                    viewpoint: 1,
                    block: 0
                }
            )
        );
        assert_ne!(draw(&a, Stream::Run), draw(&Streams::new(43), Stream::Run));
    }

    /// Every stream has its own id: the packed ids of the evaluation and
    /// frame-scale streams meet neither each other nor the others'.
    #[test]
    fn stream_ids_do_not_collide() {
        let streams = [
            Stream::Run,
            Stream::Viewpoint(0),
            Stream::Viewpoint(1),
            Stream::Beams {
                viewpoint: 0,
                block: 0,
            },
            Stream::Beams {
                viewpoint: 1,
                block: 1,
            },
            Stream::FrameScale(0),
            Stream::FrameScale(1),
            Stream::FrameScale(u32::MAX),
            Stream::GridOffset,
            Stream::RegistrationBelief,
        ];
        let mut ids: Vec<u64> = streams.iter().map(|s| s.id()).collect();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), streams.len());
    }
}
