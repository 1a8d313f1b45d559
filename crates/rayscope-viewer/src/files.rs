//! A small file browser in egui itself (no native dialog, so it works on any desktop and in
//! headless tests): folders, `.toml` scene files and mesh files (`.obj`, `.ply`, `.gltf`, `.glb`), one click to open.

use std::path::{Path, PathBuf};

use rayscope::scene::MESH_EXTENSIONS;

/// The browser's state.
pub struct FileBrowser {
    /// The folder listed.
    pub dir: PathBuf,
    entries: Vec<(String, bool)>,
    error: Option<String>,
}

/// What the user did in the browser this frame.
pub enum BrowserAction {
    /// Nothing yet.
    None,
    /// Open this file.
    Open(PathBuf),
    /// Close without opening.
    Cancel,
}

impl FileBrowser {
    /// A browser listing `dir`.
    pub fn new(dir: PathBuf) -> FileBrowser {
        let mut b = FileBrowser { dir, entries: Vec::new(), error: None };
        b.refresh();
        b
    }

    fn refresh(&mut self) {
        self.entries.clear();
        match std::fs::read_dir(&self.dir) {
            Ok(rd) => {
                for e in rd.flatten() {
                    let name = e.file_name().to_string_lossy().into_owned();
                    let is_dir = e.file_type().map(|t| t.is_dir()).unwrap_or(false);
                    let ext = Path::new(&name).extension().and_then(|x| x.to_str()).map(str::to_ascii_lowercase);
                    if (is_dir && !name.starts_with('.'))
                        || ext.as_deref().is_some_and(|e| e == "toml" || MESH_EXTENSIONS.contains(&e))
                    {
                        self.entries.push((name, is_dir));
                    }
                }
                self.entries.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
                self.error = None;
            }
            Err(e) => self.error = Some(format!("{}: {e}", self.dir.display())),
        }
    }

    /// Show the browser in a window; returns what the user chose.
    pub fn show(&mut self, ctx: &egui::Context) -> BrowserAction {
        let mut action = BrowserAction::None;
        let mut go: Option<PathBuf> = None;
        egui::Window::new("Open scene or OBJ").collapsible(false).default_size([420.0, 400.0]).show(ctx, |ui| {
            ui.horizontal(|ui| {
                if ui.button("⬆ Up").on_hover_text("The parent folder").clicked() {
                    go = self.dir.parent().map(Path::to_path_buf);
                }
                ui.label(self.dir.display().to_string());
            });
            if let Some(e) = &self.error {
                ui.colored_label(egui::Color32::LIGHT_RED, e);
            }
            ui.separator();
            egui::ScrollArea::vertical().max_height(300.0).show(ui, |ui| {
                for (name, is_dir) in &self.entries {
                    let label = if *is_dir { format!("📁 {name}") } else { name.clone() };
                    if ui.selectable_label(false, label).clicked() {
                        let p = self.dir.join(name);
                        if *is_dir {
                            go = Some(p);
                        } else {
                            action = BrowserAction::Open(p);
                        }
                    }
                }
            });
            ui.separator();
            if ui.button("Cancel").on_hover_text("Close without opening anything").clicked() {
                action = BrowserAction::Cancel;
            }
        });
        if let Some(d) = go {
            self.dir = d;
            self.refresh();
        }
        action
    }
}
