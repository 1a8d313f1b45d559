//! What the window needs of the desktop session. The viewer draws through X11 (eframe's `x11`
//! feature; a Wayland desktop runs it under XWayland), so it needs `DISPLAY`: without one it
//! says so and how to get a virtual display, instead of winit's internal message. And Mesa's
//! Vulkan device-select layer looks for a Wayland compositor whenever wgpu starts (it calls
//! libwayland's `wl_display_connect`), which prints "error: XDG_RUNTIME_DIR is invalid or not
//! set in the environment." where the session has no runtime dir (ssh, CI, `cargo test`).
//! Nothing is wrong then, so such a process gets a private, empty runtime dir, in which the
//! probe finds no compositor and fails quietly.

use std::path::Path;

/// How to run the viewer where there is no display.
pub const NO_DISPLAY_HINT: &str = "on a machine without a display, run it under a virtual one: \
    `xvfb-run -a rayscope view ...` (Debian: `apt-get install xvfb xauth`), with \
    `WGPU_BACKEND=vulkan` where there is no GPU (Mesa's software Vulkan driver, lavapipe: \
    `apt-get install mesa-vulkan-drivers`)";

/// An error naming the missing display and [`NO_DISPLAY_HINT`], or `Ok` where there is one.
pub fn check_display() -> anyhow::Result<()> {
    let missing = std::env::var_os("DISPLAY").is_none_or(|d| d.is_empty());
    if cfg!(all(unix, not(target_vendor = "apple"))) && missing {
        anyhow::bail!("no display found: DISPLAY is not set (the viewer opens an X11 window); {NO_DISPLAY_HINT}");
    }
    Ok(())
}

/// Whether the process lacks a usable runtime dir: `XDG_RUNTIME_DIR` unset, relative or not a
/// directory (libwayland's complaint).
pub fn runtime_dir_missing() -> bool {
    std::env::var_os("XDG_RUNTIME_DIR").is_none_or(|d| {
        let d = Path::new(&d);
        !d.is_absolute() || !d.is_dir()
    })
}

/// Where [`runtime_dir_missing`], make `dir` (private to the user, as a runtime dir must be)
/// the process's `XDG_RUNTIME_DIR`; returns whether it did. Call it before wgpu starts.
///
/// # Safety
///
/// As [`std::env::set_var`]: no other thread may read or write the environment meanwhile,
/// so call it before starting threads that could (the window, the render worker, wgpu).
pub unsafe fn quiet_wayland_probe(dir: &Path) -> std::io::Result<bool> {
    if !cfg!(all(unix, not(target_vendor = "apple"))) || !runtime_dir_missing() {
        return Ok(false);
    }
    std::fs::create_dir_all(dir)?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700))?;
    }
    let dir = std::path::absolute(dir)?;
    // SAFETY: the caller guarantees that no other thread touches the environment.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", dir) };
    Ok(true)
}
