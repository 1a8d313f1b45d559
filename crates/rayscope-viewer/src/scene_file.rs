//! The "Scene file" window: the structure of the glTF files the scene read (their nodes,
//! meshes and primitives), each material with the Phong values it was mapped to, and the
//! warnings of what the loaders skipped. It opens by itself for a scene that has any of these
//! (the top bar's "Scene file" button opens it again once closed).

use egui::Color32;
use rayscope::scene::Scene;

/// Where the window's open flag lives in egui's memory.
fn open_id() -> egui::Id {
    egui::Id::unique("rayscope-scene-file-open")
}

/// Whether the scene has anything the window shows.
pub fn has_contents(scene: &Scene) -> bool {
    !(scene.outline.is_empty() && scene.warnings.is_empty())
}

/// Open the window (again).
pub fn open(ctx: &egui::Context) {
    ctx.data_mut(|d| d.insert_temp(open_id(), true));
}

/// Show the window for `scene` while it is open (nothing for a scene without glTF files or
/// warnings).
pub fn scene_file_window(ctx: &egui::Context, scene: &Scene) {
    if !has_contents(scene) {
        return;
    }
    let mut open = ctx.data_mut(|d| *d.get_temp_mut_or(open_id(), true));
    egui::Window::new("Scene file")
        .open(&mut open)
        .default_width(740.0)
        .default_height(760.0)
        .default_pos([320.0, 60.0])
        .vscroll(true)
        .show(ctx, |ui| contents(ui, scene));
    ctx.data_mut(|d| d.insert_temp(open_id(), open));
}

fn contents(ui: &mut egui::Ui, scene: &Scene) {
    let (materials, structure): (Vec<&String>, Vec<&String>) =
        scene.outline.iter().partition(|l| l.starts_with("material "));
    if !structure.is_empty() {
        egui::CollapsingHeader::new(format!("glTF structure ({} lines)", structure.len())).default_open(true).show(
            ui,
            |ui| {
                for line in structure {
                    ui.monospace(line.as_str()).on_hover_text(
                        "A node of the file's scene (indented under its parent, with the form of its transform \
                         and what it places), or a primitive it placed: triangles, vertices, attributes, material",
                    );
                }
            },
        );
    }
    if !materials.is_empty() {
        egui::CollapsingHeader::new(format!("Materials ({}): glTF -> Phong", materials.len())).default_open(true).show(
            ui,
            |ui| {
                for line in materials {
                    ui.label(line.as_str()).on_hover_text(
                        "The glTF factors and the Phong values rayscope renders with: kd = base colour × (1 − \
                         metallic), ks = mix(0.04, base colour, metallic) × (1 − roughness), shininess = 2/α² − 2 \
                         (α = roughness²), transparency from the alpha mode; files rayscope wrote carry the exact \
                         values (README, \"glTF materials\")",
                    );
                }
            },
        );
    }
    if !scene.warnings.is_empty() {
        egui::CollapsingHeader::new(format!("Skipped ({})", scene.warnings.len())).default_open(true).show(ui, |ui| {
            for w in &scene.warnings {
                ui.colored_label(Color32::from_rgb(230, 180, 80), w)
                    .on_hover_text("What the loaders accepted but did not use");
            }
        });
    }
}
