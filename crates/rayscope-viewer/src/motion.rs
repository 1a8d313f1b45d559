//! Motion along paths in the viewer: each moving object's and the moving camera's path drawn
//! (a polyline of the evaluated curve, the keys marked with crosses), rays coloured by their
//! shutter time, and the *Motion* panel (the paths listed, the interpolation shown and edited,
//! and the timeline: the still or a frame of the animation, a frame slider and *Play*).

use egui::Ui;
use rayscope::animation::{AnimationSettings, MAX_FRAME};
use rayscope::math::{Vec3, Vec3A};
use rayscope::motion::{Interpolation, MotionPath};
use rayscope::record::RecordedRay;
use rayscope::scene::Scene;

use crate::overlay::{LegendEntry, Lines};
use crate::state::ViewerState;

/// An object's path.
pub const PATH_COLOR: [f32; 4] = [0.95, 0.95, 0.3, 1.0];
/// The camera's path.
pub const CAMERA_PATH_COLOR: [f32; 4] = [0.3, 1.0, 0.6, 1.0];
/// A path's keys (crosses).
pub const KEY_COLOR: [f32; 4] = [1.0, 0.3, 1.0, 1.0];

/// Polyline points per segment between two keys: a cubic's bend is smooth at this step.
const STEPS_PER_SEGMENT: usize = 32;

/// The shutter times at the ends of the time colour ramp: blue when the shutter opens, orange
/// when it closes.
const TIME_START_COLOR: [f32; 3] = [0.2, 0.45, 1.0];
const TIME_END_COLOR: [f32; 3] = [1.0, 0.55, 0.05];

/// The colour of shutter time `t` in `[0, 1]`: blue at 0 through grey-violet to orange at 1.
pub fn time_color(t: f32) -> [f32; 4] {
    let t = t.clamp(0.0, 1.0);
    let [a, b] = [TIME_START_COLOR, TIME_END_COLOR];
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t, 1.0]
}

/// A recorded ray's colour by its shutter time (every ray of a sample carries the sample's);
/// `None` for a ray without a recorded traversal (its time unknown).
pub fn ray_time_color(ray: &RecordedRay) -> Option<[f32; 4]> {
    ray.traversal.as_ref().map(|t| time_color(t.time))
}

/// The legend's entries for rays coloured by time.
pub fn time_legend() -> Vec<LegendEntry> {
    [(0.0, "rays at shutter time 0 (opens)"), (0.5, "rays at time 0.5"), (1.0, "rays at time 1 (closes)")]
        .into_iter()
        .map(|(t, meaning)| LegendEntry { color: time_color(t), meaning: meaning.into() })
        .collect()
}

/// The legend's entries for the paths drawn.
pub fn path_legend() -> Vec<LegendEntry> {
    [(PATH_COLOR, "an object's path"), (CAMERA_PATH_COLOR, "the camera's path"), (KEY_COLOR, "a path's key")]
        .into_iter()
        .map(|(color, meaning)| LegendEntry { color, meaning: meaning.into() })
        .collect()
}

/// One moving thing of a scene and its path, with the point the path moves (a mesh's centroid,
/// a sphere's centre, the camera's eye) before the path's translation.
pub struct MovingThing<'a> {
    /// What moves, for the panel: "mesh NAME", "sphere N" or "camera".
    pub name: String,
    /// Its path.
    pub path: &'a MotionPath,
    /// The point drawn along the path, untranslated.
    pub anchor: Vec3A,
    /// Whether it is the camera.
    pub camera: bool,
}

/// Every moving mesh, sphere and the camera of `scene`, in that order.
pub fn moving_things(scene: &Scene) -> Vec<MovingThing<'_>> {
    let mut out = Vec::new();
    for m in &scene.meshes {
        if let Some(path) = &m.motion {
            let anchor = m.positions.iter().copied().sum::<Vec3A>() / m.positions.len().max(1) as f32;
            out.push(MovingThing { name: format!("mesh {}", m.name), path, anchor, camera: false });
        }
    }
    for (i, s) in scene.spheres.iter().enumerate() {
        if let Some(path) = &s.motion {
            out.push(MovingThing { name: format!("sphere {i}"), path, anchor: s.center, camera: false });
        }
    }
    if let Some(path) = &scene.camera_path {
        out.push(MovingThing { name: "camera".into(), path, anchor: scene.camera().position, camera: true });
    }
    out
}

/// Draw every path of `scene` into `out`: the evaluated curve as a polyline and a cross at
/// each key (`r`: the scene's radius, for the crosses' size).
pub fn path_lines(out: &mut Lines, scene: &Scene, r: f32) {
    for thing in moving_things(scene) {
        let color = if thing.camera { CAMERA_PATH_COLOR } else { PATH_COLOR };
        let steps = STEPS_PER_SEGMENT * (thing.path.keys().len() - 1);
        let points = thing.path.polyline(steps);
        for w in points.windows(2) {
            out.line(Vec3::from(thing.anchor + w[0]), Vec3::from(thing.anchor + w[1]), color);
        }
        for k in thing.path.keys() {
            out.cross(Vec3::from(thing.anchor) + k.translation, 0.03 * r, KEY_COLOR);
        }
    }
}

/// The *Motion* panel: the scene's paths with their keys, *Show paths*, and the interpolation
/// of every path, which rebuilds the scene's BVH when changed.
pub fn panel(ui: &mut Ui, st: &mut ViewerState) {
    let things = moving_things(&st.scene);
    if things.is_empty() {
        ui.label("Nothing in this scene moves along a path").on_hover_text(
            "Give a mesh or sphere `motion = { keys = [[t, [x, y, z]], ...], interpolation = \"catmull-rom\" }` \
             in a scene file, or the camera a [camera_motion] table",
        );
        return;
    }
    ui.checkbox(&mut st.show_paths, "Show paths").on_hover_text(
        "Draw each moving object's path (yellow) and the camera's (green) through the scene: the curve the \
         renderer evaluates, its keys marked with crosses",
    );
    let current = things[0].path.interpolation();
    let mut chosen = current;
    egui::ComboBox::from_label("Interpolation")
        .selected_text(interpolation_label(current))
        .show_ui(ui, |ui| {
            for i in Interpolation::ALL {
                ui.selectable_value(&mut chosen, i, interpolation_label(i)).on_hover_text(interpolation_tooltip(i));
            }
        })
        .response
        .on_hover_text(
            "How every path goes between its keys (all paths of the scene; with two keys both are the same line). \
             Changing it rebuilds the BVH around the new paths",
        );
    for t in &things {
        let keys = t.path.keys();
        let lines: Vec<String> = keys
            .iter()
            .map(|k| {
                format!("t {:.3}: ({:.3}, {:.3}, {:.3})", k.time, k.translation.x, k.translation.y, k.translation.z)
            })
            .collect();
        ui.label(format!("{}: {} keys, {}", t.name, keys.len(), t.path.interpolation().name()))
            .on_hover_text(format!("Keys (scene time in seconds: translation):\n{}", lines.join("\n")));
    }
    if chosen != current {
        st.set_motion_interpolation(chosen);
    }
    timeline(ui, st, last_key_time(&st.scene));
}

/// The time of the last key of any path of `scene` (0 without paths).
fn last_key_time(scene: &Scene) -> f32 {
    moving_things(scene).iter().filter_map(|t| t.path.keys().last()).map(|k| k.time).fold(0.0, f32::max)
}

/// The last frame the timeline offers: the scene's `[animation] frames`' last, else the frame
/// at the last key (at least 1).
pub fn last_frame(animation: &AnimationSettings, last_key: f32) -> u32 {
    animation
        .frames
        .map_or_else(|| ((last_key as f64 * animation.fps).ceil() as u32).clamp(1, MAX_FRAME), |r| r.end - 1)
}

/// The timeline: *Animate* (the still, or a frame of the animation), the frame slider with
/// the span of scene time the frame exposes, and *Play*.
fn timeline(ui: &mut Ui, st: &mut ViewerState, last_key: f32) {
    let animation = st.animation();
    let first = animation.frames.map_or(0, |r| r.start);
    let last = last_frame(&animation, last_key).max(first);
    let mut animate = st.frame.is_some();
    ui.checkbox(&mut animate, "Animate").on_hover_text(format!(
        "Off: the still, scene time 0 to 1 s (motion blur over it). On: a frame of the animation at {} fps, \
         exposing [F / fps, (F + shutter) / fps] with a shutter of {} of a frame, as `render --frame F` \
         renders it (the scene's [animation], or the defaults). The view's camera stays the trackball's",
        animation.fps, animation.shutter
    ));
    let mut frame = st.frame.map(|f| f.clamp(first, last));
    if animate != frame.is_some() {
        frame = animate.then_some(first);
        st.playing = false;
    }
    if let Some(f) = frame.as_mut() {
        let shutter = animation.shutter_of(*f);
        ui.add(egui::Slider::new(f, first..=last).text("Frame")).on_hover_text(
            "The frame the ray tracer shows; the BVH is rebuilt around the moving shapes over the frame's span only",
        );
        ui.horizontal(|ui| {
            let label = if st.playing { "Pause" } else { "Play" };
            if ui.button(label).on_hover_text("Step through the frames at the animation's rate, looping").clicked() {
                st.playing = !st.playing;
            }
            ui.label(format!("scene time {:.4} to {:.4} s", shutter.open, shutter.close)).on_hover_text(
                "The span of the scene's timeline this frame exposes: each sample sees the scene at a time in it",
            );
        });
        if st.playing {
            // One frame per 1 / fps seconds of wall time; the image shows what it has gathered.
            let now = ui.input(|i| i.time);
            let step = 1.0 / animation.fps;
            let since = st.play_clock.get_or_insert(now);
            if now - *since >= step {
                *since = now;
                *f = if *f >= last { first } else { *f + 1 };
            }
            ui.ctx().request_repaint_after(std::time::Duration::from_secs_f64(step));
        } else {
            st.play_clock = None;
        }
    }
    st.set_frame(frame);
}

fn interpolation_label(i: Interpolation) -> &'static str {
    match i {
        Interpolation::Linear => "Linear",
        Interpolation::CatmullRom => "Catmull-Rom",
    }
}

fn interpolation_tooltip(i: Interpolation) -> &'static str {
    match i {
        Interpolation::Linear => "Straight segments between keys, at constant speed within each",
        Interpolation::CatmullRom => {
            "A smooth curve through the keys, its velocity at each key the difference of its neighbours over \
             their time apart (one-sided at the ends)"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayscope::animation::Shutter;
    use rayscope::scene::{LoadContext, SceneDesc};

    const SCENE: &str = r#"
[[sphere]]
center = [0, 0, 0]
radius = 0.2
motion = { keys = [[0, [0, 0, 0]], [0.5, [1, 1, 0]], [1, [2, 0, 0]]], interpolation = "catmull-rom" }

[camera_motion]
keys = [[0, [0, 0, 0]], [1, [0.1, 0, 0]]]
"#;

    fn scene() -> Scene {
        let d = SceneDesc::from_toml(SCENE, std::path::Path::new("s.toml")).unwrap();
        Scene::from_desc(&d, &LoadContext::default()).unwrap()
    }

    #[test]
    fn paths_are_drawn_through_their_keys() {
        let scene = scene();
        let mut out = Lines::default();
        path_lines(&mut out, &scene, 1.0);
        let path: Vec<Vec3> = out.0.iter().filter(|v| v.color == PATH_COLOR).map(|v| Vec3::from_array(v.pos)).collect();
        // Two segments of 32 steps: 64 lines, two vertices each, from the first key to the last.
        assert_eq!(path.len(), 2 * 2 * STEPS_PER_SEGMENT);
        assert_eq!(path[0], Vec3::ZERO);
        assert!(path.last().unwrap().distance(Vec3::new(2.0, 0.0, 0.0)) < 1e-6);
        // It passes through the middle key, and every point is the curve the renderer uses.
        assert!(path.iter().any(|p| p.distance(Vec3::new(1.0, 1.0, 0.0)) < 1e-6));
        let sphere_path = scene.spheres[0].motion.as_ref().unwrap();
        assert!(path.iter().all(|p| (0..=64).any(|i| sphere_path.at(i as f32 / 64.0).distance((*p).into()) < 1e-6)));
        // The keys' crosses (three lines each) and the camera's path.
        assert_eq!(out.0.iter().filter(|v| v.color == KEY_COLOR).count(), (3 + 2) * 6);
        assert!(out.0.iter().any(|v| v.color == CAMERA_PATH_COLOR));
    }

    #[test]
    fn the_state_draws_paths_and_edits_the_interpolation() {
        let mut st = ViewerState::new("cornell-box-motion", None);
        let path_vertices = |st: &ViewerState| st.overlay_lines().iter().filter(|v| v.color == PATH_COLOR).count();
        assert_eq!(path_vertices(&st), 2 * 4 * STEPS_PER_SEGMENT, "four segments of the loop");
        let key = st.overlay_key();
        st.show_paths = false;
        assert_eq!(path_vertices(&st), 0);
        assert_ne!(st.overlay_key(), key, "the lines are made again when paths are hidden");
        st.show_paths = true;
        st.select_pixel(340, 460);
        let generation = st.generation;
        st.set_motion_interpolation(Interpolation::Linear);
        assert_eq!(st.scene.spheres[0].motion.as_ref().unwrap().interpolation(), Interpolation::Linear);
        assert!(st.generation > generation, "the render restarts");
        assert!(st.selection.is_some(), "the selection stays");
        // The scene is loaded again with the override.
        st.reload();
        assert_eq!(st.scene.spheres[0].motion.as_ref().unwrap().interpolation(), Interpolation::Linear);
        // Rays coloured by time: each camera ray in its sample's colour.
        st.color_by = crate::overlay::ColorBy::Time;
        let lines = st.overlay_lines();
        for sample in &st.selection.as_ref().unwrap().first().trace.samples {
            let c = time_color(sample.time);
            assert!(lines.iter().any(|v| v.color == c), "sample {} at {}", sample.index, sample.time);
        }
    }

    #[test]
    fn the_timeline_shows_a_frame_and_keeps_it_across_reloads() {
        let mut st = ViewerState::new("cornell-box-motion", None);
        assert_eq!(st.scene.shutter(), Shutter::STILL);
        let animation = st.animation();
        assert_eq!(last_frame(&animation, 1.0), 23, "the scene's frames 0..24");
        let default = AnimationSettings::default();
        assert_eq!(last_frame(&default, 2.0), 48, "else the frame at the last key");
        st.select_pixel(340, 460);
        let generation = st.generation;
        st.set_frame(Some(6));
        assert_eq!(st.scene.shutter(), animation.shutter_of(6));
        assert!(st.generation > generation && st.selection.is_some());
        // The debugger traces the frame: its samples' rays meet the sphere where it is then.
        st.reload();
        assert_eq!(st.scene.shutter(), animation.shutter_of(6), "a reload keeps the frame");
        st.set_frame(None);
        assert_eq!(st.scene.shutter(), Shutter::STILL);
    }

    #[test]
    fn time_colours_run_from_blue_to_orange() {
        let near = |a: [f32; 4], b: [f32; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6);
        assert!(near(time_color(0.0), TIME_START_COLOR) && near(time_color(1.0), TIME_END_COLOR));
        assert!(time_color(0.25)[2] > time_color(0.75)[2]);
    }
}
