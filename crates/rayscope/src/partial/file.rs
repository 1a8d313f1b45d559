//! The partial film as an OpenEXR file, readable by any EXR tool: channels `R`, `G`, `B`
//! (the mean so far, a preview), `samples` (the count, u32), and the exact `f64` sums as the
//! two 32-bit halves of their bits (`sum.R.hi`, `sum.R.lo`, ... as u32, which EXR stores as
//! they are); header attributes `rayscope.*` hold the fingerprint, the part or checkpoint,
//! the count of dropped samples and the sums' residuals. Written atomically
//! ([`crate::output::write_file`]): a killed writer leaves the previous file whole.

use std::collections::HashMap;
use std::path::Path;

use exr::prelude::*;

use super::fingerprint::Fingerprint;
use super::part::{Part, Split};
use super::{Checkpoint, PartialFilm, Portion};
use crate::error::{Error, Result as RayResult};
use crate::film::{Film, PixelSum, Residual};

/// The format's version, in `rayscope.partial`: a reader refuses others.
const VERSION: i32 = 1;

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// Write `partial` to `path` (an `.exr`), atomically.
pub fn write_partial(partial: &PartialFilm, path: &Path) -> RayResult<()> {
    let film = &partial.film;
    let size = (film.width() as usize, film.height() as usize);
    let preview = film.pixels();
    let mut channels = Vec::new();
    for (c, name) in CHANNELS.iter().enumerate() {
        channels.push(AnyChannel::new(*name, FlatSamples::F32(preview.iter().map(|p| p[c]).collect())));
        let bits = |shift: u32| film.sums().map(|s| (s[c].to_bits() >> shift) as u32).collect();
        channels.push(AnyChannel::new(format!("sum.{name}.hi").as_str(), FlatSamples::U32(bits(32))));
        channels.push(AnyChannel::new(format!("sum.{name}.lo").as_str(), FlatSamples::U32(bits(0))));
    }
    channels.push(AnyChannel::new("samples", FlatSamples::U32(film.counts().to_vec())));
    let mut attributes = LayerAttributes::named("rayscope partial film");
    let mut set = |key: &str, value: AttributeValue| {
        attributes.other.insert(Text::from(key), value);
    };
    let text = |s: &str| AttributeValue::Text(Text::new_or_panic(ascii(s)));
    set("rayscope.partial", AttributeValue::I32(VERSION));
    set("rayscope.scene", text(&partial.fingerprint.scene));
    set("rayscope.sceneHash", text(&partial.fingerprint.scene_hash));
    set("rayscope.settings", text(&partial.fingerprint.settings));
    set("rayscope.dropped", text(&film.dropped().to_string()));
    set("rayscope.residuals", text(&residuals_text(film.residuals())));
    match &partial.portion {
        Portion::Part(p) => {
            set("rayscope.part", AttributeValue::I32(p.index as i32));
            set("rayscope.parts", AttributeValue::I32(p.count as i32));
            set("rayscope.split", text(p.split.name()));
        }
        Portion::Checkpoint(c) => {
            set("rayscope.targetSpp", AttributeValue::I32(c.target_spp.map_or(0, |t| t as i32)));
            set("rayscope.frames", AttributeValue::I32(c.frames as i32));
        }
    }
    let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(SmallVec::from_vec(channels)));
    crate::output::write_file(path, |w| Image::from_layer(layer).write().to_buffered(w).map_err(std::io::Error::other))
}

/// `s` with every character outside printable ASCII escaped (EXR text is bytes).
fn ascii(s: &str) -> String {
    s.chars()
        .map(|c| if c == '\n' || (' '..='~').contains(&c) { c.to_string() } else { c.escape_unicode().to_string() })
        .collect()
}

/// Residuals as text: `pixel r g b` per line, each value its `f64` bits in hex.
fn residuals_text(residuals: &[Residual]) -> String {
    residuals
        .iter()
        .map(|r| {
            format!("{} {:x} {:x} {:x}\n", r.pixel, r.value[0].to_bits(), r.value[1].to_bits(), r.value[2].to_bits())
        })
        .collect()
}

/// Read a partial film written by [`write_partial`]; errors name `path` and what is wrong
/// ("not a rayscope partial film", a missing channel, ...).
pub fn read_partial(path: &Path) -> RayResult<PartialFilm> {
    let bad = |m: String| Error::parse(path, None, m);
    let reader = crate::io::file::open(path)?.buffered();
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(reader)
        .map_err(|e| bad(format!("not a readable OpenEXR file ({e})")))?;
    let not_partial = || bad("not a rayscope partial film (an EXR file without its rayscope.* attributes)".into());
    let layer = image.layer_data.first().ok_or_else(not_partial)?;
    let attrs = &layer.attributes.other;
    let version = match attrs.get(&Text::from("rayscope.partial")) {
        Some(AttributeValue::I32(v)) => *v,
        _ => return Err(not_partial()),
    };
    if version != VERSION {
        return Err(bad(format!("partial film format {version}; this rayscope reads format {VERSION}")));
    }
    let text = |key: &str| match attrs.get(&Text::from(key)) {
        Some(AttributeValue::Text(t)) => Ok(t.to_string()),
        _ => Err(bad(format!("missing attribute {key}"))),
    };
    let int = |key: &str| match attrs.get(&Text::from(key)) {
        Some(AttributeValue::I32(v)) if *v >= 0 => Ok(Some(*v as u32)),
        Some(_) => Err(bad(format!("attribute {key} is not a count"))),
        None => Ok(None),
    };
    let fingerprint = Fingerprint {
        scene: text("rayscope.scene")?,
        scene_hash: text("rayscope.sceneHash")?,
        settings: text("rayscope.settings")?,
    };
    let portion = match (int("rayscope.part")?, int("rayscope.parts")?) {
        (Some(index), Some(count)) => {
            let split = text("rayscope.split")?;
            let split = Split::from_name(&split).ok_or_else(|| bad(format!("unknown split '{split}'")))?;
            Portion::Part(Part::new(index, count, split).map_err(|e| bad(e.to_string()))?)
        }
        _ => Portion::Checkpoint(Checkpoint {
            target_spp: int("rayscope.targetSpp")?.filter(|t| *t > 0),
            frames: int("rayscope.frames")?.ok_or_else(|| bad("missing attribute rayscope.frames".into()))?,
        }),
    };
    let dropped: u64 = text("rayscope.dropped")?.parse().map_err(|_| bad("bad rayscope.dropped".into()))?;
    let size = layer.size;
    let (width, height) = (size.0 as u32, size.1 as u32);
    let channels: HashMap<String, &FlatSamples> =
        layer.channel_data.list.iter().map(|c| (c.name.to_string(), &c.sample_data)).collect();
    let u32s = |name: &str| match channels.get(name) {
        Some(FlatSamples::U32(v)) => Ok(v.as_slice()),
        _ => Err(bad(format!("missing u32 channel {name}"))),
    };
    let counts = u32s("samples")?.to_vec();
    let halves: Vec<(&[u32], &[u32])> = CHANNELS
        .iter()
        .map(|c| Ok((u32s(&format!("sum.{c}.hi"))?, u32s(&format!("sum.{c}.lo"))?)))
        .collect::<RayResult<_>>()?;
    let sums: Vec<PixelSum> = (0..counts.len())
        .map(|i| std::array::from_fn(|c| f64::from_bits(u64::from(halves[c].0[i]) << 32 | u64::from(halves[c].1[i]))))
        .collect();
    if sums.iter().flatten().any(|v| !v.is_finite()) {
        return Err(bad("a pixel's sum is not finite".into()));
    }
    let residuals =
        parse_residuals(&text("rayscope.residuals")?).ok_or_else(|| bad("bad rayscope.residuals".into()))?;
    let film = Film::from_parts(width, height, sums, counts, residuals, dropped).map_err(|e| bad(e.into()))?;
    Ok(PartialFilm { fingerprint, portion, film })
}

fn parse_residuals(text: &str) -> Option<Vec<Residual>> {
    text.lines()
        .map(|line| {
            let mut f = line.split(' ');
            let pixel = f.next()?.parse().ok()?;
            let mut value = [0.0; 3];
            for v in &mut value {
                *v = f64::from_bits(u64::from_str_radix(f.next()?, 16).ok()?);
                if !v.is_finite() {
                    return None;
                }
            }
            f.next().is_none().then_some(Residual { pixel, value })
        })
        .collect()
}
