//! The thin lens in a scene file's camera table: `[camera] aperture` and `focus_distance`
//! (depth of field, [`crate::lens`]). The renderer reads the lens from
//! [`RenderSettings::aperture`] and [`RenderSettings::focus_distance`], where flags and the
//! viewer set it; a scene file names it where it belongs, on the camera, and its loader maps
//! those keys onto the settings. `[render] aperture` and `focus_distance`, the keys of the
//! first release, stay accepted as aliases; a lens given in both tables, or in `[camera_end]`
//! (the lens does not move), is an error naming its line. `scenes --export` writes the lens
//! into the camera table.

use serde::Deserialize;

use super::desc::SceneDesc;
use crate::settings::RenderSettings;

/// The lens keys of a table, read beside the scene's own parse (which accepts them in the
/// camera tables and checks their types), ignoring every other key.
#[derive(Default, Deserialize)]
struct LensKeys {
    aperture: Option<f32>,
    focus_distance: Option<f32>,
}

impl LensKeys {
    fn is_empty(&self) -> bool {
        self.aperture.is_none() && self.focus_distance.is_none()
    }

    /// The first key given, for errors.
    fn first_key(&self) -> &'static str {
        if self.aperture.is_some() { "aperture" } else { "focus_distance" }
    }
}

/// The tables that may name a lens.
#[derive(Default, Deserialize)]
struct LensTables {
    #[serde(default)]
    camera: LensKeys,
    #[serde(default)]
    camera_end: LensKeys,
    #[serde(default)]
    render: LensKeys,
}

/// A lens key that is wrong: the table and key it is in, and why.
pub(super) struct BadLens {
    /// `camera` or `camera_end`.
    pub table: &'static str,
    /// `aperture` or `focus_distance`.
    pub key: &'static str,
    /// What is wrong.
    pub message: String,
}

/// Move the camera table's lens keys of scene file `text` into `desc`'s render settings
/// (making them if it has none). Checks their values: an aperture finite and at least 0, a
/// focus distance finite and above 0.
pub(super) fn apply(text: &str, desc: &mut SceneDesc) -> Result<(), BadLens> {
    // The scene's own parse has accepted the text and the keys' types.
    let Ok(tables) = toml::from_str::<LensTables>(text) else { return Ok(()) };
    let bad = |table, key, message: &str| Err(BadLens { table, key, message: message.into() });
    if !tables.camera_end.is_empty() {
        let message = "the lens does not move: give it in [camera]";
        return bad("camera_end", tables.camera_end.first_key(), message);
    }
    let LensKeys { aperture, focus_distance } = tables.camera;
    if let Some(a) = aperture {
        if !(a.is_finite() && a >= 0.0) {
            return bad("camera", "aperture", &format!("aperture {a} must be a finite lens radius of 0 or more"));
        }
        if tables.render.aperture.is_some() {
            return bad("camera", "aperture", "also given in [render] (its old place): give it once");
        }
    }
    if let Some(d) = focus_distance {
        if !(d.is_finite() && d > 0.0) {
            return bad("camera", "focus_distance", &format!("focus distance {d} must be finite and greater than 0"));
        }
        if tables.render.focus_distance.is_some() {
            return bad("camera", "focus_distance", "also given in [render] (its old place): give it once");
        }
    }
    if aperture.is_some() || focus_distance.is_some() {
        let render = desc.render.get_or_insert_with(RenderSettings::default);
        render.aperture = aperture.unwrap_or(render.aperture);
        render.focus_distance = focus_distance.or(render.focus_distance);
    }
    Ok(())
}

/// `desc` as a TOML table with its lens in the camera table (where a lens is set: an aperture
/// above 0 or a focus distance), not in the render table.
pub(super) fn export(desc: &SceneDesc) -> toml::Table {
    let mut table = toml::Table::try_from(desc).expect("scene descriptions always serialise");
    let lens = desc.render.as_ref().map(|r| (r.aperture, r.focus_distance));
    if let Some(toml::Value::Table(render)) = table.get_mut("render") {
        render.remove("aperture");
        render.remove("focus_distance");
    }
    if let Some((aperture, focus)) = lens.filter(|(a, f)| *a != 0.0 || f.is_some()) {
        let camera = table.entry("camera").or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let toml::Value::Table(camera) = camera {
            camera.insert("aperture".into(), toml::Value::Float(aperture.into()));
            if let Some(f) = focus {
                camera.insert("focus_distance".into(), toml::Value::Float(f.into()));
            }
        }
    }
    table
}
