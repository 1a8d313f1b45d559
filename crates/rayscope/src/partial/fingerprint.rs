//! What identifies a render: its scene (a label and a hash of what defines it) and its
//! settings. Parts merge, and checkpoints resume, only under the same fingerprint.

use crate::settings::RenderSettings;

/// The identity of a render.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fingerprint {
    /// The scene as the user named it (a built-in's name or a file's path), for messages.
    pub scene: String,
    /// A hash, in hex, of everything that defines the scene: the file's bytes, or the
    /// built-in's name, and any option that changes the scene (the command line's camera and
    /// environment flags).
    pub scene_hash: String,
    /// The settings, as TOML (one `key = value` per line, so differences can be named).
    pub settings: String,
}

impl Fingerprint {
    /// The fingerprint of rendering a scene identified by `scene` and `scene_hash` with
    /// `settings`.
    pub fn new(scene: &str, scene_hash: &str, settings: &RenderSettings) -> Fingerprint {
        Fingerprint {
            scene: scene.to_string(),
            scene_hash: scene_hash.to_string(),
            settings: toml::to_string(settings).unwrap_or_else(|e| format!("unserialisable settings: {e}")),
        }
    }

    /// The settings it holds, or `None` if its TOML is not a valid [`RenderSettings`].
    pub fn render_settings(&self) -> Option<RenderSettings> {
        toml::from_str(&self.settings).ok()
    }

    /// What differs between `self` and `other`, in words (empty when they are the same):
    /// "the scene (a.toml, hash 1f.. against b.toml, hash 2e..)", "spp (4 against 8)".
    pub fn differences(&self, other: &Fingerprint) -> Vec<String> {
        let mut out = Vec::new();
        if self.scene_hash != other.scene_hash {
            out.push(format!(
                "the scene ({} with hash {} against {} with hash {})",
                self.scene, self.scene_hash, other.scene, other.scene_hash
            ));
        }
        let mine = settings_lines(&self.settings);
        let theirs = settings_lines(&other.settings);
        let keys: std::collections::BTreeSet<&String> = mine.keys().chain(theirs.keys()).collect();
        for key in keys {
            let (a, b) = (mine.get(key), theirs.get(key));
            if a != b {
                let show = |v: Option<&String>| v.map_or("unset".to_string(), |v| v.clone());
                out.push(format!("{key} ({} against {})", show(a), show(b)));
            }
        }
        out
    }
}

/// The settings' TOML as `key` (or `table.key`) to value.
fn settings_lines(toml: &str) -> std::collections::BTreeMap<String, String> {
    let mut table = String::new();
    let mut out = std::collections::BTreeMap::new();
    for line in toml.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            table = format!("{name}.");
        } else if let Some((k, v)) = line.split_once(" = ") {
            out.insert(format!("{table}{k}"), v.to_string());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_name_the_settings() {
        let a = Fingerprint::new("cornell-box", "00ff", &RenderSettings::default());
        assert!(a.differences(&a).is_empty());
        let b = Fingerprint::new("cornell-box", "00ff", &RenderSettings { spp: 4, ..RenderSettings::default() });
        assert_eq!(a.differences(&b), ["spp (1 against 4)"]);
        let c = Fingerprint::new("teapot", "11aa", &RenderSettings::default());
        assert_eq!(a.differences(&c).len(), 1);
        assert!(a.differences(&c)[0].starts_with("the scene (cornell-box"), "{:?}", a.differences(&c));
    }
}
