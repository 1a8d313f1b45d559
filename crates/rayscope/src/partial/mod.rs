//! Partial films: a render's samples split into parts (for many machines) or saved part-way
//! (checkpoints), kept as OpenEXR files, and merged into the image that one render would
//! have made, bit for bit (the film's sums are exact: see [`crate::film::Film`]).
//!
//! - [`part`]: which samples of which pixels part `K` of `N` renders, and rendering it;
//! - [`fingerprint`]: what identifies a render (scene, settings), and what differs between two;
//! - [`file`]: the partial film as an OpenEXR file (sums, counts, fingerprint), written
//!   atomically;
//! - [`merge`]: checking that parts make one whole render, and adding them up.

pub mod file;
pub mod fingerprint;
pub mod merge;
pub mod part;

use crate::film::Film;
use fingerprint::Fingerprint;
use part::Part;

/// What a partial film holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Portion {
    /// Part `part.index` of `part.count` of a render.
    Part(Part),
    /// A progressive render's state, to be resumed.
    Checkpoint(Checkpoint),
}

/// Where a progressive render stood when its checkpoint was written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Checkpoint {
    /// The samples per pixel the render stops at (`None`: open-ended; it then ends by time
    /// or Ctrl-C).
    pub target_spp: Option<u32>,
    /// Frames rendered.
    pub frames: u32,
}

/// A film with what it is a portion of: the contents of a partial film file.
#[derive(Clone, Debug, PartialEq)]
pub struct PartialFilm {
    /// The render the film belongs to.
    pub fingerprint: Fingerprint,
    /// Which part of it, or which checkpoint.
    pub portion: Portion,
    /// The sums and counts.
    pub film: Film,
}
