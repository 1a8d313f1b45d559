//! Image files: formats, atomic replacement, errors.

use rayscope::film::FloatImage;
use rayscope::output::{Encoding, parse_pfm, read_pfm, to_rgb8, write_image};

fn image() -> FloatImage {
    FloatImage { width: 3, height: 2, channels: 3, data: (0..18).map(|i| i as f32 / 10.0 - 0.2).collect() }
}

#[test]
fn pfm_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.pfm");
    write_image(&image(), &p, Encoding::Linear).unwrap();
    assert_eq!(read_pfm(&p).unwrap(), image());
    let grey = FloatImage { width: 2, height: 2, channels: 1, data: vec![f32::NAN, 1.0, -1.0, 2.5] };
    write_image(&grey, &p, Encoding::Linear).unwrap();
    let back = read_pfm(&p).unwrap();
    assert!(back.data[0].is_nan() && back.data[1..] == grey.data[1..]);
}

/// Found by the `image` fuzz target: a header whose width x height x channels overflowed u32
/// panicked (with overflow checks) or wrapped to a small size and read the wrong pixels.
#[test]
fn pfm_sizes_past_u32_are_truncated_data_not_a_panic() {
    let path = std::path::Path::new("big.pfm");
    for header in ["PF\n1431655766 1\n-1\n", "Pf\n65536 65536\n-1\n", "PF\n4294967295 4294967295\n1\n"] {
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend_from_slice(&[0; 64]);
        let err = parse_pfm(&bytes, path).unwrap_err().to_string();
        assert!(err.contains("truncated data"), "{header:?}: {err}");
    }
}

/// Found by the `image` fuzz target: a file that stopped right after the scale (with no pixels
/// to read, "Pf 0 2 0") sliced its data from one byte past its end.
#[test]
fn a_pfm_header_without_its_last_whitespace_is_truncated_not_a_panic() {
    let path = std::path::Path::new("cut.pfm");
    for bytes in ["Pf\n0 2\n0", "PF 0 0 -1"] {
        let err = parse_pfm(bytes.as_bytes(), path).unwrap_err().to_string();
        assert!(err.contains("truncated header"), "{bytes:?}: {err}");
    }
    assert_eq!(parse_pfm(b"Pf 0 2 -1\n", path).unwrap().data, Vec::<f32>::new(), "an empty image is whole");
}

/// Found by the `image` fuzz target: an image 0 pixels wide and 800 million rows high took
/// seconds (a loop over its empty rows); it reads at once.
#[test]
fn an_empty_pfm_of_many_rows_reads_at_once() {
    // Rows are no longer flipped one by one: before the fix this test ran for 43 s (it asserts
    // the result, not the time; a return of the hang shows as a test that does not finish).
    let img = parse_pfm(b"Pf\n0\n4000000000\n-1\n", std::path::Path::new("tall.pfm")).unwrap();
    assert_eq!((img.width, img.height, img.data.len()), (0, 4_000_000_000, 0));
}

#[test]
fn png_and_exr_are_written() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["png", "exr"] {
        let p = dir.path().join(format!("a.{ext}"));
        write_image(&image(), &p, Encoding::Linear).unwrap();
        assert!(std::fs::metadata(&p).unwrap().len() > 0);
    }
    let png = image::open(dir.path().join("a.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (3, 2));
    assert_eq!(png.get_pixel(0, 0).0, [0, 0, 0], "clamped");
    assert_eq!(png.get_pixel(1, 0).0, [26, 51, 77], "x255, rounded");
}

#[test]
fn eight_bit_encodings() {
    let img = FloatImage { width: 3, height: 1, channels: 1, data: vec![0.5, 2.0, f32::NAN] };
    assert_eq!(to_rgb8(&img, Encoding::Linear), vec![128, 255, 0]);
    assert_eq!(to_rgb8(&img, Encoding::Srgb)[0], 188);
}

#[test]
fn failed_writes_leave_existing_files_alone() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("keep.png");
    std::fs::write(&p, b"old").unwrap();
    assert!(write_image(&image(), &dir.path().join("no/such/dir/x.png"), Encoding::Linear).is_err());
    let bad_ext = dir.path().join("keep.jpg");
    assert!(write_image(&image(), &bad_ext, Encoding::Linear).is_err());
    assert!(!bad_ext.exists());
    assert_eq!(std::fs::read(&p).unwrap(), b"old");
    // No temporary files are left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[cfg(unix)]
#[test]
fn written_files_are_ordinary_files() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.png");
    write_image(&image(), &p, Encoding::Linear).unwrap();
    assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o644);
}

#[cfg(unix)]
#[test]
fn a_replaced_file_keeps_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.png");
    std::fs::write(&p, b"old").unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o640)).unwrap();
    write_image(&image(), &p, Encoding::Linear).unwrap();
    assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o7777, 0o640);
    assert!(image::open(&p).is_ok());
}

#[cfg(unix)]
#[test]
fn symbolic_links_are_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("real")).unwrap();
    std::fs::write(d.join("real/target.png"), b"old").unwrap();
    std::os::unix::fs::symlink("real/target.png", d.join("link.png")).unwrap();
    // A link to a link, and a link whose target does not exist yet.
    std::os::unix::fs::symlink("link.png", d.join("link2.png")).unwrap();
    std::os::unix::fs::symlink("real/new.png", d.join("dangling.png")).unwrap();
    for name in ["link.png", "link2.png", "dangling.png"] {
        write_image(&image(), &d.join(name), Encoding::Linear).unwrap();
        assert!(std::fs::symlink_metadata(d.join(name)).unwrap().file_type().is_symlink(), "{name} stays a link");
    }
    assert!(image::open(d.join("real/target.png")).is_ok());
    assert!(image::open(d.join("real/new.png")).is_ok());
    // The temporary files were beside the targets, and are gone.
    assert_eq!(std::fs::read_dir(d.join("real")).unwrap().count(), 2);
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 4);
}

#[test]
fn only_regular_files_are_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("folder.png");
    std::fs::create_dir(&p).unwrap();
    let err = write_image(&image(), &p, Encoding::Linear).unwrap_err().to_string();
    assert!(err.contains("not a regular file"), "{err}");
    assert!(p.is_dir());
}

#[test]
fn errors_name_the_output_and_say_the_system_error_once() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("no/such/dir/x.png");
    let err = write_image(&image(), &p, Encoding::Linear).unwrap_err();
    let text = err.to_string();
    assert!(text.starts_with(&p.display().to_string()), "{text}");
    assert!(!text.contains(".partial") && !text.contains(".rayscope-"), "{text}");
    assert_eq!(text.matches("os error").count(), 1, "{text}");
}
