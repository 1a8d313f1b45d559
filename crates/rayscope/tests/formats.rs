//! glTF 2.0 and PLY in, OBJ and glTF out: round trips of every built-in scene (bit for bit),
//! hand-made glTF files (node transforms, indexed and non-indexed primitives, embedded and
//! external buffers, GLB, a texture, a camera, lights), PLY in its three encodings, and
//! hostile files (a clear error naming the file and the element, never a panic).

mod common;

use std::path::{Path, PathBuf};

use base64::Engine;
use rayscope::Error;
use rayscope::camera::CameraDesc;
use rayscope::export::{ExportFormat, export_scene};
use rayscope::light::Light;
use rayscope::math::{Vec3, Vec3A};
use rayscope::render::render;
use rayscope::scene::{LoadContext, MeshDesc, Scene, SceneDesc, builtin};
use rayscope::settings::RenderSettings;
use serde_json::{Value, json};

fn small() -> RenderSettings {
    RenderSettings { width: 48, height: 48, ..RenderSettings::default() }
}

#[test]
fn every_builtin_scene_exported_to_obj_and_gltf_renders_the_same_bits() {
    let assets = common::assets("every_builtin_scene_exported_to_obj_and_gltf_renders_the_same_bits");
    for b in builtin::BUILTINS {
        if b.needs_assets && assets.is_none() {
            continue;
        }
        let scene = common::builtin_scene(b.name, assets.as_ref());
        let want = render(&scene, &small(), &|_| {}).film;
        for format in [ExportFormat::Obj, ExportFormat::Gltf] {
            let dir = tempfile::tempdir().unwrap();
            let exported = export_scene(&scene, format, dir.path(), b.name).unwrap();
            let back = Scene::load(exported.scene_file.to_str().unwrap(), None).unwrap();
            assert_eq!(back.triangle_count(), scene.triangle_count(), "{} {format:?}", b.name);
            assert_eq!(back.lights, scene.lights, "{} {format:?}", b.name);
            let got = render(&back, &small(), &|_| {}).film;
            assert!(got == want, "{} exported as {format:?} renders other pixels", b.name);
        }
    }
}

/// Bytes of little-endian f32s.
fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(bytes))
}

/// A 2x1 PNG: red on the left, blue on the right.
fn png() -> Vec<u8> {
    let img = image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255]).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A glTF document: one triangle at z = 0 (x, y in [0, 1]) as an indexed primitive and the
/// same triangle again as a non-indexed one, placed by a parent node (translated by (10, 0, 0)
/// in TRS form) and a child (scaled by 2 in matrix form); a camera node at (0, 0, 5) looking
/// down −z; a point light of intensity 4 at (0, 2, 0) and a directional light; a textured
/// material. `buffer` is the buffer's `uri` (or none, for a GLB's chunk).
fn document(buffer: Option<String>, len: usize) -> Value {
    let mut buf = json!({ "byteLength": len });
    if let Some(uri) = buffer {
        buf["uri"] = json!(uri);
    }
    json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_clearcoat"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "type": "point", "color": [1, 1, 1], "intensity": 4 },
            { "type": "directional", "color": [1, 0.5, 0.25], "intensity": 2 }
        ] } },
        "scene": 0,
        "scenes": [{ "nodes": [0, 2, 3, 4] }],
        "nodes": [
            { "name": "parent", "translation": [10, 0, 0], "children": [1] },
            { "name": "child", "mesh": 0, "matrix": [2,0,0,0, 0,2,0,0, 0,0,2,0, 0,0,0,1] },
            { "name": "camera", "camera": 0, "translation": [0, 0, 5] },
            { "name": "lamp", "translation": [0, 2, 0], "extensions": { "KHR_lights_punctual": { "light": 0 } } },
            { "name": "sun", "extensions": { "KHR_lights_punctual": { "light": 1 } } }
        ],
        "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.5, "znear": 0.1 } }],
        "meshes": [{ "name": "tri", "primitives": [
            { "attributes": { "POSITION": 0, "TEXCOORD_0": 2 }, "indices": 1, "material": 0 },
            { "attributes": { "POSITION": 0 } },
            { "attributes": { "POSITION": 0 }, "mode": 1 }
        ] }],
        "materials": [{ "name": "red-blue", "pbrMetallicRoughness": {
            "baseColorTexture": { "index": 0 }, "metallicFactor": 0, "roughnessFactor": 1 } }],
        "textures": [{ "source": 0 }],
        "images": [{ "uri": data_uri(&png()) }],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0, 0, 0], "max": [1, 1, 0] },
            { "bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR" },
            { "bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 6 },
            { "buffer": 0, "byteOffset": 44, "byteLength": 24 }
        ],
        "buffers": [buf]
    })
}

/// The buffer of [`document`]: positions, u16 indices (padded to 4 bytes), texture coordinates.
fn buffer() -> Vec<u8> {
    let mut b = f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    b.extend([0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    b.extend([0, 0]);
    b.extend(f32s(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]));
    b
}

/// A GLB file of `doc` and binary chunk `bin`.
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let pad = |mut v: Vec<u8>, with: u8| {
        v.resize(v.len().next_multiple_of(4), with);
        v
    };
    let json = pad(serde_json::to_vec(doc).unwrap(), b' ');
    let bin = pad(bin.to_vec(), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// The scene of the mesh file at `path`, as `rayscope render FILE` loads it.
fn load(path: &Path) -> rayscope::Result<Scene> {
    Scene::load(path.to_str().unwrap(), None)
}

fn check_hand_made(scene: &Scene, file: &str) {
    // Two TRIANGLES primitives (the LINES one is skipped with a warning naming it).
    assert_eq!(scene.meshes.len(), 2, "{file}");
    for m in &scene.meshes {
        // Scaled by 2 (child's matrix), then moved by (10, 0, 0) (parent's TRS); the camera
        // keeps the file's coordinates (no normalisation).
        let corners: Vec<Vec3A> = m.triangles[0].iter().map(|&i| m.positions[i as usize]).collect();
        assert_eq!(
            corners,
            vec![Vec3A::new(10.0, 0.0, 0.0), Vec3A::new(12.0, 0.0, 0.0), Vec3A::new(10.0, 2.0, 0.0)],
            "{file}"
        );
        assert!(m.normals.iter().all(|n| (*n - Vec3A::Z).length() < 1e-6), "{file}: smooth normals");
    }
    let warned = scene.warnings.join("\n");
    assert!(warned.contains("primitive 2") && warned.contains("Lines"), "{file}: {warned}");
    assert!(warned.contains("KHR_materials_clearcoat"), "{file}: {warned}");
    // The textured primitive: texture coordinates as given, the image's rows turned over.
    let textured = &scene.meshes[0];
    assert_eq!(textured.uvs.len(), 3, "{file}");
    let m = &scene.materials[textured.materials[0] as usize];
    let t = &scene.textures[m.texture.expect("textured")];
    assert_eq!((t.width, t.height), (2, 1));
    assert_eq!(t.texels[0], Vec3::new(1.0, 0.0, 0.0));
    assert_eq!(scene.materials[scene.meshes[1].materials[0] as usize].name, "default");
    match &scene.camera {
        CameraDesc::LookAt { eye, target, up, fov } => {
            assert_eq!((*eye, *target, *up), (Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, 4.0), Vec3::Y));
            assert!((fov - 0.5f32.to_degrees()).abs() < 1e-4, "{fov}");
        }
        other => panic!("{file}: {other:?}"),
    }
    // The point light: intensity / d² at the centre of the vertices; the directional light far
    // away against its direction (−z), with its colour × intensity.
    let center = Vec3::new(32.0 / 3.0, 2.0 / 3.0, 0.0);
    match &scene.lights[..] {
        [Light::Point { position, color }, Light::Point { position: far, color: sun }] => {
            assert_eq!(*position, Vec3::new(0.0, 2.0, 0.0));
            let d2 = position.distance_squared(center);
            assert!((*color - Vec3::splat(4.0 / d2)).length() < 1e-5, "{color}");
            assert!(far.z > 100.0 && (far.x - center.x).abs() < 1e-3, "{far}");
            assert_eq!(*sun, Vec3::new(2.0, 1.0, 0.5));
        }
        other => panic!("{file}: {other:?}"),
    }
    assert!(scene.outline.iter().any(|l| l.contains("node 1 'child' (matrix)")), "{:?}", scene.outline);
    assert!(scene.outline.iter().any(|l| l.contains("material 0 'red-blue'") && l.contains("mapped")));
}

#[test]
fn hand_made_gltf_files_load_with_embedded_external_and_glb_buffers() {
    let dir = tempfile::tempdir().unwrap();
    let bin = buffer();
    let embedded = dir.path().join("embedded.gltf");
    std::fs::write(&embedded, serde_json::to_vec(&document(Some(data_uri(&bin)), bin.len())).unwrap()).unwrap();
    let external = dir.path().join("external.gltf");
    std::fs::write(dir.path().join("tri angle.bin"), &bin).unwrap();
    std::fs::write(&external, serde_json::to_vec(&document(Some("tri%20angle.bin".into()), bin.len())).unwrap())
        .unwrap();
    let binary = dir.path().join("binary.glb");
    std::fs::write(&binary, glb(&document(None, bin.len()), &bin)).unwrap();
    for path in [&embedded, &external, &binary] {
        let scene = load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        check_hand_made(&scene, &path.display().to_string());
    }
    // In a scene file, as a [[mesh]], placed like any mesh.
    let toml = dir.path().join("s.toml");
    std::fs::write(&toml, "[[mesh]]\npath = \"binary.glb\"\nnormalize = true\n").unwrap();
    let scene = load(&toml).unwrap();
    let max = scene.meshes[0].positions.iter().map(|p| p.length()).fold(0.0, f32::max);
    assert!(max <= 1.0 + 1e-5, "{max}");
}

/// Write `doc` (with `bin` as its data: buffer) as `name` and load it: the error's text.
fn gltf_error(doc: Value, name: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    match load(&path) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("{name} loaded"),
    }
}

#[test]
fn hostile_gltf_files_are_errors_naming_the_file_and_element() {
    let bin = buffer();
    let good = || document(Some(data_uri(&bin)), bin.len());
    // A buffer shorter than it says.
    let truncated = document(Some(data_uri(&bin[..40])), bin.len());
    let e = gltf_error(truncated, "truncated.gltf");
    assert!(e.contains("truncated.gltf") && e.contains("buffer 0"), "{e}");
    // An index past the vertices.
    let mut bad_index = bin.clone();
    bad_index[36..38].copy_from_slice(&7u16.to_le_bytes());
    let e = gltf_error(document(Some(data_uri(&bad_index)), bin.len()), "index.gltf");
    assert!(e.contains("index.gltf") && e.contains("out of range") && e.contains("primitive 0"), "{e}");
    // Positions of the wrong type.
    let mut wrong = good();
    wrong["accessors"][0]["type"] = json!("VEC2");
    let e = gltf_error(wrong, "type.gltf");
    assert!(e.contains("accessor 0 (POSITION)") && e.contains("Vec2"), "{e}");
    // An accessor reaching past its view.
    let mut long = good();
    long["accessors"][2]["count"] = json!(30);
    let e = gltf_error(long, "long.gltf");
    assert!(e.contains("accessor 2 (TEXCOORD_0)") && e.contains("reach past"), "{e}");
    // An offset so large that the arithmetic would overflow.
    let mut huge = good();
    huge["accessors"][0]["byteOffset"] = json!(u64::MAX);
    let e = gltf_error(huge, "huge.gltf");
    assert!(e.contains("huge.gltf"), "{e}");
    // A view past its buffer.
    let mut view = good();
    view["bufferViews"][2]["byteOffset"] = json!(1000);
    let e = gltf_error(view, "view.gltf");
    assert!(e.contains("bufferView 2"), "{e}");
    // A reference to nothing, and no JSON at all.
    let mut dangling = good();
    dangling["nodes"][1]["mesh"] = json!(9);
    assert!(gltf_error(dangling, "dangling.gltf").contains("not a valid glTF document"));
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in [
        ("junk.gltf", b"{ not json".to_vec()),
        ("short.glb", b"glTF\x02\0\0\0".to_vec()),
        ("lying.glb", [b"glTF".as_slice(), &2u32.to_le_bytes(), &9999u32.to_le_bytes()].concat()),
        ("chunk.glb", glb(&good(), &bin)[..30].to_vec()),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = load(&path).err().unwrap_or_else(|| panic!("{name} loaded")).to_string();
        assert!(e.contains(name), "{e}");
    }
    // A node that is its own child: skipped with a warning, not followed forever.
    let mut cycle = good();
    cycle["nodes"][1]["children"] = json!([0]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cycle.gltf");
    std::fs::write(&path, serde_json::to_vec(&cycle).unwrap()).unwrap();
    let scene = load(&path).unwrap();
    assert!(scene.warnings.iter().any(|w| w.contains("met twice")), "{:?}", scene.warnings);
}

/// A PLY file of a unit square (a quad face) and a triangle, with normals and texture
/// coordinates and an extra property and element to read past, in `format`.
fn ply(format: &str) -> Vec<u8> {
    let verts: [[f32; 8]; 5] = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0],
        [1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        [0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0],
        [0.5, 0.5, 1.0, 0.0, 1.0, 0.0, 0.5, 0.5],
    ];
    let faces: [&[i32]; 2] = [&[0, 1, 2, 3], &[0, 1, 4]];
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment made by a test\nelement vertex 5\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float s\n\
         property float t\nproperty uchar quality\nelement face 2\nproperty list uchar int vertex_indices\n\
         property int flags\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    )
    .into_bytes();
    let big = format == "binary_big_endian";
    let f = |v: f32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let i = |v: i32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    for v in &verts {
        if format == "ascii" {
            let words: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            out.extend(format!("{} 7\n", words.join(" ")).bytes());
        } else {
            v.iter().for_each(|&x| out.extend(f(x)));
            out.push(7);
        }
    }
    for face in faces {
        if format == "ascii" {
            let words: Vec<String> = face.iter().map(|x| x.to_string()).collect();
            out.extend(format!("{} {} 0\n", face.len(), words.join(" ")).bytes());
        } else {
            out.push(face.len() as u8);
            face.iter().for_each(|&x| out.extend(i(x)));
            out.extend(i(0));
        }
    }
    if format == "ascii" {
        out.extend(b"0 1\n");
    } else {
        out.extend(i(0));
        out.extend(i(1));
    }
    out
}

/// The scene of the PLY file `bytes` (named `name`), in the file's own coordinates.
fn load_ply(bytes: &[u8], name: &str) -> rayscope::Result<Scene> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    let desc = SceneDesc { meshes: vec![MeshDesc { path: Some(path), ..MeshDesc::default() }], ..SceneDesc::default() };
    Scene::from_desc(&desc, &LoadContext::default())
}

#[test]
fn ply_in_ascii_and_both_byte_orders_gives_the_same_triangles() {
    let scenes: Vec<Scene> = ["ascii", "binary_little_endian", "binary_big_endian"]
        .iter()
        .map(|f| load_ply(&ply(f), &format!("{f}.ply")).unwrap_or_else(|e| panic!("{f}: {e}")))
        .collect();
    let m = &scenes[0].meshes[0];
    // The quad fanned into two triangles, then the triangle.
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
    assert_eq!(m.positions[4], Vec3A::new(0.5, 0.5, 1.0));
    assert_eq!(m.normals[4], Vec3A::Y);
    assert_eq!(m.uvs[2], rayscope::math::Vec2::new(1.0, 1.0));
    for s in &scenes[1..] {
        let n = &s.meshes[0];
        assert_eq!((&n.positions, &n.normals, &n.uvs, &n.triangles), (&m.positions, &m.normals, &m.uvs, &m.triangles));
    }
}

#[test]
fn hostile_ply_files_are_errors_naming_the_file_and_element() {
    let good = String::from_utf8(ply("ascii")).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        // The header claims more vertices than the file can hold.
        ("lying.ply", good.replace("element vertex 5", "element vertex 500000000").into_bytes(), "'vertex' elements"),
        // Fewer faces than counted: the file ends first.
        (
            "short.ply",
            good.replace("element face 2", "element face 3").replace("element edge 1", "element edge 0").into_bytes(),
            "face 2",
        ),
        // A face list longer than the file.
        (
            "list.ply",
            {
                // The second face's count says 200 corners: the file ends inside its list.
                let mut b = ply("binary_little_endian");
                let header = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
                b[header + 5 * 33 + 21] = 200;
                b
            },
            "face 1: the file ends inside it",
        ),
        ("index.ply", good.replace("3 0 1 4 0", "3 0 1 9 0").into_bytes(), "out of range"),
        ("word.ply", good.replace("0.5 0.5 1 ", "0.5 x 1 ").into_bytes(), "vertex 4"),
        ("noply.ply", b"solid cube\nfacet normal 0 0 1\n".to_vec(), "not a PLY file"),
        (
            "nofaces.ply",
            good.replace("element face 2", "element face 0").replace("4 0 1 2 3 0\n3 0 1 4 0\n", "").into_bytes(),
            "no faces",
        ),
    ];
    for (name, bytes, want) in cases {
        let e = match load_ply(&bytes, name) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("{name} loaded"),
        };
        assert!(e.contains(name) && e.contains(want), "{name}: {e}");
    }
    // An ASCII error names its line.
    let bad = good.replace("0.5 0.5 1 ", "0.5 x 1 ");
    match load_ply(bad.as_bytes(), "line.ply") {
        Err(Error::Parse { line: Some(line), .. }) => assert_eq!(line, 25),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_gltf_scene_exported_by_rayscope_keeps_its_exact_phong_values() {
    let scene = common::builtin_scene("cornell-box", None);
    let dir = tempfile::tempdir().unwrap();
    export_scene(&scene, ExportFormat::Gltf, dir.path(), "box").unwrap();
    let doc: Value = serde_json::from_slice(&std::fs::read(dir.path().join("box.gltf")).unwrap()).unwrap();
    let m = &doc["materials"][0];
    assert!(m["extras"]["rayscope"]["kd"].is_array(), "{m}");
    assert!(m["pbrMetallicRoughness"]["baseColorFactor"].is_array(), "{m}");
    let back = load(&dir.path().join("box.gltf")).unwrap();
    let want: Vec<_> = scene.materials.iter().skip(1).map(|m| (m.kd, m.ks, m.shininess, m.transparency)).collect();
    for m in back.materials.iter().skip(1) {
        assert!(want.contains(&(m.kd, m.ks, m.shininess, m.transparency)), "{m:?}");
    }
    let _: PathBuf = dir.path().to_path_buf();
}
