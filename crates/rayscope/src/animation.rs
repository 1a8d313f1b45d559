//! Animations: the scene's timeline, the span of it one image exposes ([`Shutter`]), and how
//! the frames of an animation map onto it ([`AnimationSettings`], [`FrameRange`],
//! [`AnimationSettings::frame`]).
//!
//! Motion keys ([`crate::motion`]) are times in **seconds of scene time**. Each sample of an
//! image draws a *shutter fraction* `u` in `[0, 1)` (the sampler's time, what rays carry); the
//! image's [`Shutter`] maps it to scene time `open + u (close - open)`. A still render exposes
//! [`Shutter::STILL`], `[0, 1]`: scene time equals the fraction bit for bit, so the still's
//! motion blur is what it always was (keys over `[0, 1]` are its shutter). Frame `F` of an
//! animation at `fps` frames per second opens at `F / fps` and stays open for `shutter / fps`
//! (`shutter = 0.5` is a film camera's 180-degree shutter).
//!
//! Nothing here renders or writes files: the CLI (`render --frames`, `--frame`), the viewer's
//! timeline and a cluster's array task per frame all map a frame number onto its shutter and
//! output file with these functions, so they agree by construction.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The span of scene time one image exposes: a sample at shutter fraction `u` in `[0, 1)`
/// sees the scene at [`Shutter::time`]`(u)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shutter {
    /// Scene time (seconds) when the shutter opens.
    pub open: f32,
    /// Scene time when it closes (at least `open`).
    pub close: f32,
}

impl Shutter {
    /// A still image's shutter: `[0, 1]`, where scene time is the shutter fraction itself.
    pub const STILL: Shutter = Shutter { open: 0.0, close: 1.0 };

    /// The scene time of shutter fraction `u` in `[0, 1)`: `open + u (close - open)`, never
    /// past `close` (rounding could step over it, outside the BVH's bounds for the interval).
    /// For [`Shutter::STILL`] it is `u`, exactly.
    #[inline]
    pub fn time(self, u: f32) -> f32 {
        (self.open + u * (self.close - self.open)).min(self.close)
    }

    /// Whether this is [`Shutter::STILL`].
    pub fn is_still(self) -> bool {
        self == Shutter::STILL
    }
}

impl Default for Shutter {
    fn default() -> Shutter {
        Shutter::STILL
    }
}

/// The highest frame number accepted (frame `F` opens at `F / fps`: at 24 fps this is over
/// eleven hours of scene time, where `f32` seconds still resolve a tenth of a millisecond).
pub const MAX_FRAME: u32 = 1_000_000;

/// The highest frame rate accepted.
pub const MAX_FPS: f64 = 10_000.0;

/// The frames of an animation, `start` included and `end` excluded, written as Rust's ranges:
/// `A..B` (`B` excluded) or `A..=B` (`B` included). Frames count from 0; frame 0 opens at
/// scene time 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct FrameRange {
    /// The first frame.
    pub start: u32,
    /// One past the last frame.
    pub end: u32,
}

impl FrameRange {
    /// Parse `A..B` or `A..=B` (frame numbers 0 to [`MAX_FRAME`], at least one frame); the
    /// error says what is wrong.
    pub fn parse(s: &str) -> Result<FrameRange, String> {
        let syntax = || format!("'{s}' is not a range of frames: write A..B (B excluded) or A..=B (B included)");
        let (a, b, inclusive) = match s.trim().split_once("..") {
            Some((a, b)) => match b.strip_prefix('=') {
                Some(b) => (a, b, true),
                None => (a, b, false),
            },
            None => return Err(syntax()),
        };
        let number = |v: &str| -> Result<u32, String> {
            let v = v.trim();
            if v.starts_with('-') {
                return Err(format!("'{s}': frame {v} is negative; frames count from 0"));
            }
            match v.parse::<u64>() {
                Ok(n) if n <= MAX_FRAME as u64 => Ok(n as u32),
                Ok(n) => Err(format!("'{s}': frame {n} is past the last frame accepted, {MAX_FRAME}")),
                Err(_) => Err(syntax()),
            }
        };
        let (start, last) = (number(a)?, number(b)?);
        let end = if inclusive { last + 1 } else { last };
        if end <= start {
            let what = if inclusive { "ends before it starts" } else { "holds no frame (B is excluded)" };
            return Err(format!("'{s}' {what}: write A..B with A < B, or A..=B with A <= B"));
        }
        Ok(FrameRange { start, end })
    }

    /// The range of one frame.
    pub fn single(frame: u32) -> FrameRange {
        FrameRange { start: frame, end: frame + 1 }
    }

    /// The frame numbers, in order.
    pub fn frames(self) -> std::ops::Range<u32> {
        self.start..self.end
    }

    /// How many frames.
    pub fn len(self) -> u32 {
        self.end - self.start
    }

    /// Never: a range holds at least one frame ([`FrameRange::parse`] refuses empty ones).
    pub fn is_empty(self) -> bool {
        self.end <= self.start
    }
}

impl fmt::Display for FrameRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..{}", self.start, self.end)
    }
}

impl TryFrom<String> for FrameRange {
    type Error = String;
    fn try_from(s: String) -> Result<FrameRange, String> {
        FrameRange::parse(&s)
    }
}

impl From<FrameRange> for String {
    fn from(r: FrameRange) -> String {
        r.to_string()
    }
}

/// How a scene is animated: its frame rate, the frames to render and each frame's shutter.
/// A scene file's `[animation]` table; `render --fps/--frames/--shutter` override it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnimationSettings {
    /// Frames per second of scene time.
    pub fps: f64,
    /// The frames `render --frames` renders when the flag gives none (`None`: the flag must).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<FrameRange>,
    /// The part of a frame's duration the shutter is open, 0 to 1 (0.5: a 180-degree shutter).
    pub shutter: f64,
}

impl Default for AnimationSettings {
    fn default() -> AnimationSettings {
        AnimationSettings { fps: 24.0, frames: None, shutter: 0.5 }
    }
}

/// One frame of an animation: its number, the span of scene time it exposes and its file.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The frame number.
    pub number: u32,
    /// The scene time it exposes.
    pub shutter: Shutter,
    /// Its output file ([`frame_path`]).
    pub output: PathBuf,
}

impl AnimationSettings {
    /// Check the values: `fps` finite, above 0 and at most [`MAX_FPS`]; `shutter` in `[0, 1]`.
    pub fn validate(&self) -> Result<(), crate::Error> {
        let bad = |m: String| Err(crate::Error::Invalid(m));
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= MAX_FPS) {
            return bad(format!("fps {}: must be a number above 0, at most {MAX_FPS}", self.fps));
        }
        if !(self.shutter.is_finite() && (0.0..=1.0).contains(&self.shutter)) {
            return bad(format!("shutter {}: must be 0 to 1 (a fraction of the frame's duration)", self.shutter));
        }
        Ok(())
    }

    /// The scene time frame `frame` exposes: `[frame / fps, (frame + shutter) / fps]`,
    /// computed in `f64` and rounded once to `f32`.
    pub fn shutter_of(&self, frame: u32) -> Shutter {
        let open = frame as f64 / self.fps;
        let close = (frame as f64 + self.shutter) / self.fps;
        Shutter { open: open as f32, close: (close as f32).max(open as f32) }
    }

    /// Frame `number` of a render whose `-o` is `output`: its shutter and its file.
    pub fn frame(&self, number: u32, output: &Path) -> Frame {
        Frame { number, shutter: self.shutter_of(number), output: frame_path(output, number) }
    }
}

/// The file of frame `frame` for `-o output`: `_` and the number, zero-padded to at least four
/// digits, before the extension (`out.png`, 7: `out_0007.png`; `a/b.exr`, 12345:
/// `a/b_12345.exr`).
pub fn frame_path(output: &Path, frame: u32) -> PathBuf {
    let stem = output.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match output.extension() {
        Some(ext) => format!("{stem}_{frame:04}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{frame:04}"),
    };
    output.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn still_shutter_time_is_the_fraction_bit_for_bit() {
        for i in 0..10_000 {
            let u = i as f32 / 10_000.0;
            assert_eq!(Shutter::STILL.time(u).to_bits(), u.to_bits());
        }
        assert_eq!(Shutter::STILL.time(1.0 - f32::EPSILON / 2.0), 1.0 - f32::EPSILON / 2.0);
    }

    #[test]
    fn frame_times_are_the_closed_form() {
        let a = AnimationSettings { fps: 24.0, frames: None, shutter: 0.5 };
        assert_eq!(a.shutter_of(0), Shutter { open: 0.0, close: 1.0 / 48.0 });
        assert_eq!(a.shutter_of(24), Shutter { open: 1.0, close: 1.0 + 1.0 / 48.0 });
        assert_eq!(a.shutter_of(12), Shutter { open: 0.5, close: 0.5 + 1.0 / 48.0 });
        let whole = AnimationSettings { fps: 1.0, frames: None, shutter: 1.0 };
        assert_eq!(whole.shutter_of(0), Shutter::STILL, "frame 0 at 1 fps, open all frame, is the still");
        let s = a.shutter_of(7);
        for i in 0..=100 {
            let t = s.time(i as f32 / 100.0);
            assert!(t >= s.open && t <= s.close, "{t} outside {s:?}");
        }
        assert_eq!(s.time(0.0), s.open);
        let instant = AnimationSettings { shutter: 0.0, ..a }.shutter_of(5);
        assert_eq!(instant.open, instant.close);
        assert_eq!(instant.time(0.7), instant.open);
    }

    #[test]
    fn ranges_parse_in_both_rust_forms() {
        assert_eq!(FrameRange::parse("1..4"), Ok(FrameRange { start: 1, end: 4 }));
        assert_eq!(FrameRange::parse("1..=3"), Ok(FrameRange { start: 1, end: 4 }));
        assert_eq!(FrameRange::parse(" 0..=0 "), Ok(FrameRange::single(0)));
        assert_eq!(FrameRange::parse("1..4").unwrap().frames().collect::<Vec<_>>(), [1, 2, 3]);
        for (bad, want) in [
            ("4..1", "no frame"),
            ("3..3", "no frame"),
            ("3..=2", "before it starts"),
            ("-1..3", "negative"),
            ("1..-3", "negative"),
            ("1-3", "not a range"),
            ("a..b", "not a range"),
            ("0..99999999999", "past the last"),
            ("", "not a range"),
        ] {
            let e = FrameRange::parse(bad).unwrap_err();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }

    #[test]
    fn bad_settings_are_refused() {
        for fps in [0.0, -24.0, f64::NAN, f64::INFINITY, 1e9] {
            let e = AnimationSettings { fps, ..Default::default() }.validate().unwrap_err();
            assert!(e.to_string().contains("fps"), "{e}");
        }
        for shutter in [-0.1, 1.5, f64::NAN] {
            let e = AnimationSettings { shutter, ..Default::default() }.validate().unwrap_err();
            assert!(e.to_string().contains("shutter"), "{e}");
        }
        AnimationSettings::default().validate().unwrap();
    }

    #[test]
    fn frame_files_are_numbered_before_the_extension() {
        assert_eq!(frame_path(Path::new("out.png"), 7), Path::new("out_0007.png"));
        assert_eq!(frame_path(Path::new("a/b.exr"), 12345), Path::new("a/b_12345.exr"));
        assert_eq!(frame_path(Path::new("x.y.pfm"), 0), Path::new("x.y_0000.pfm"));
        let a = AnimationSettings::default();
        let f = a.frame(3, Path::new("o.png"));
        assert_eq!((f.number, f.shutter, f.output), (3, a.shutter_of(3), PathBuf::from("o_0003.png")));
    }
}
