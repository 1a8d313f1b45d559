//! The CLI with glTF and PLY: rendering them, exporting scenes to OBJ and glTF, and hostile
//! files failing with an error that names them, writing no image.

mod common;

use common::{rayscope, stderr};

/// A PLY file of one triangle.
const TRIANGLE_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
    property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
    0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

#[test]
fn render_reads_ply_and_exports_render_back() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("t.ply"), TRIANGLE_PLY).unwrap();
    let o = rayscope(dir.path(), &["render", "t.ply", "--width", "16", "--height", "16", "-o", "t.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for format in ["obj", "gltf"] {
        let o = rayscope(dir.path(), &["scenes", "--export", "t.ply", "--format", format, format]);
        assert!(o.status.success(), "{}", stderr(&o));
        let scene = dir.path().join(format).join("t.toml");
        let o = rayscope(
            dir.path(),
            &["render", scene.to_str().unwrap(), "--width", "16", "--height", "16", "-o", &format!("{format}.png")],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(
            std::fs::read(dir.path().join("t.png")).unwrap(),
            std::fs::read(dir.path().join(format!("{format}.png"))).unwrap()
        );
    }
    // Without a folder, --format is refused.
    let o = rayscope(dir.path(), &["scenes", "--export", "cube", "--format", "obj"]);
    assert!(!o.status.success());
}

#[test]
fn hostile_mesh_files_fail_naming_the_file_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let lying = TRIANGLE_PLY.replace("element face 1", "element face 1000000");
    std::fs::write(dir.path().join("lying.ply"), lying).unwrap();
    std::fs::write(dir.path().join("bad.glb"), b"glTF\x02\0\0\0\xff\xff\0\0").unwrap();
    std::fs::write(dir.path().join("bad.gltf"), br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":99,"uri":"data:application/octet-stream;base64,AAAA"}]}"#).unwrap();
    for (file, element) in [("lying.ply", "'face' elements"), ("bad.glb", "GLB"), ("bad.gltf", "buffer 0")] {
        let o = rayscope(dir.path(), &["render", file, "-o", "out.png"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{file}: {e}");
        assert!(e.contains(file) && e.contains(element), "{file}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!dir.path().join("out.png").exists(), "{file}");
        let o = rayscope(dir.path(), &["scenes", "--export", file, "--format", "gltf", "out"]);
        assert!(!o.status.success() && !dir.path().join("out").exists(), "{file}");
    }
}
