//! Merging parts: checking that partial films make exactly one whole render (one
//! fingerprint, one split into `N` parts, each part once, none missing) and adding their
//! films, which gives the one-shot render's film bit for bit.

use std::path::PathBuf;

use super::part::Part;
use super::{PartialFilm, Portion};
use crate::error::{Error, Result};
use crate::film::Film;

/// Merge `parts` (each with the file it came from, for messages) into the film of the whole
/// render. Errors name the files: another render's part, a part given twice, a part
/// missing, a checkpoint among parts.
pub fn merge_parts(parts: &[(PathBuf, PartialFilm)]) -> Result<Film> {
    let bad = |m: String| Err(Error::Invalid(m));
    let Some((first_path, first)) = parts.first() else { return bad("no partial films to merge".into()) };
    let part_of = |path: &PathBuf, p: &PartialFilm| match p.portion {
        Portion::Part(part) => Ok(part),
        Portion::Checkpoint(_) => Err(Error::Invalid(format!(
            "{}: a checkpoint, not a part (resume it with `rayscope render --resume`)",
            path.display()
        ))),
    };
    let head = part_of(first_path, first)?;
    let mut seen: Vec<Option<&PathBuf>> = vec![None; head.count as usize];
    let mut film = Film::new(first.film.width(), first.film.height());
    for (path, p) in parts {
        let part = part_of(path, p)?;
        let differences = first.fingerprint.differences(&p.fingerprint);
        if !differences.is_empty() {
            return bad(format!(
                "{} and {} are parts of different renders: {}",
                first_path.display(),
                path.display(),
                differences.join(", ")
            ));
        }
        if (part.count, part.split) != (head.count, head.split) {
            return bad(format!(
                "{} is part {} of {} split by {}, {} part {} of {} split by {}",
                first_path.display(),
                head.index,
                head.count,
                head.split.name(),
                path.display(),
                part.index,
                part.count,
                part.split.name()
            ));
        }
        if let Some(other) = seen[part.index as usize] {
            return bad(format!(
                "{} and {} are both part {} of {}",
                other.display(),
                path.display(),
                part.index,
                part.count
            ));
        }
        seen[part.index as usize] = Some(path);
        if !film.merge(&p.film) {
            return bad(format!("{}: image size differs from {}", path.display(), first_path.display()));
        }
    }
    let missing: Vec<String> = (0..head.count).filter(|&k| seen[k as usize].is_none()).map(|k| k.to_string()).collect();
    if !missing.is_empty() {
        return bad(format!(
            "missing {} {} of {} (given {} {})",
            if missing.len() == 1 { "part" } else { "parts" },
            missing.join(", "),
            head.count,
            parts.len(),
            if parts.len() == 1 { "file" } else { "files" }
        ));
    }
    Ok(film)
}

/// The indices of `count` parts that `present` lacks.
pub fn missing_parts(count: u32, present: &[Part]) -> Vec<u32> {
    (0..count).filter(|k| !present.iter().any(|p| p.index == *k)).collect()
}
