//! `--window`: a winit window with orbit controls around an impostor drawn by `altrep-display`.
//!
//! Each frame the impostor is drawn offscreen by the same display code as the headless mode
//! (so the window shows exactly what the tests check), read back, uploaded as a texture and
//! drawn scaled into the window's surface. Controls: drag with the left button turns the
//! azimuth (and the elevation where the representation has one; images with parallax and
//! cylindrical textures are captured from horizontal views, so they turn only), the wheel
//! zooms, Escape or closing the window quits.
//!
//! The viewer is built with the `window` feature only (`cargo run -p altrep-examples --features
//! window --bin …`): winit and its X11 and Wayland crates are a third of the examples' build, and
//! the default build (the test command's) leaves them out; without the feature [`run`] returns
//! [`WindowError::NotBuilt`]. Without a display (neither `DISPLAY` nor `WAYLAND_DISPLAY` set on
//! Linux) [`run`] returns [`WindowError::NoDisplay`] before touching winit.

use altrep_display::{Gpu, RgbaImage};

#[cfg(feature = "window")]
mod viewer;

/// What went wrong with the window.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    /// The examples were built without the `window` feature (winit).
    #[error(
        "built without the window viewer: rebuild with `--features window` \
         (cargo run -p altrep-examples --features window --bin …)"
    )]
    NotBuilt,
    /// No display server to open a window on.
    #[error("no display: set DISPLAY or WAYLAND_DISPLAY (the headless mode needs neither)")]
    NoDisplay,
    /// winit could not start its event loop or create the window.
    #[error("window system: {0}")]
    Window(String),
    /// No adapter can present to the window, or the surface refused its configuration.
    #[error("GPU: {0}")]
    Gpu(String),
    /// The impostor could not be set up or drawn.
    #[error("draw: {0}")]
    Draw(String),
}

/// The camera of the orbit controls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// Azimuth `α` (radians).
    pub azimuth: f64,
    /// Elevation (radians, `[−π/2, π/2]`; stays 0 when the representation has none).
    pub elevation: f64,
    /// Zoom factor of the drawn image (1 = fit the window), `[0.25, 8]`.
    pub zoom: f64,
}

/// Whether a display server is named by the environment `var` (Linux and the BSDs: `DISPLAY`
/// or `WAYLAND_DISPLAY` non-empty; other systems always have one).
pub fn check_display(var: impl Fn(&str) -> Option<String>) -> Result<(), WindowError> {
    if cfg!(all(
        unix,
        not(target_os = "macos"),
        not(target_os = "android")
    )) {
        let set = |k: &str| var(k).is_some_and(|v| !v.is_empty());
        if !set("DISPLAY") && !set("WAYLAND_DISPLAY") {
            return Err(WindowError::NoDisplay);
        }
    }
    Ok(())
}

/// Opens a window titled `title` and runs the orbit viewer until it is closed. `setup` builds
/// the impostor on the window's device (once); `draw` renders it for an orbit into an image
/// (premultiplied linear RGBA). `elevation` says whether dragging vertically changes the
/// elevation. Errors: no display, the window system, the GPU, or the first error of
/// `setup`/`draw` (which ends the loop).
#[cfg(feature = "window")]
pub fn run<D>(
    title: &str,
    elevation: bool,
    setup: impl FnOnce(&Gpu) -> Result<D, String>,
    draw: impl FnMut(&Gpu, &D, Orbit) -> Result<RgbaImage, String>,
) -> Result<(), WindowError> {
    check_display(|k| std::env::var(k).ok())?;
    viewer::run(title, elevation, setup, draw)
}

/// Built without the `window` feature: always [`WindowError::NotBuilt`] (the feature keeps
/// winit and its X11/Wayland crates out of the default build).
#[cfg(not(feature = "window"))]
pub fn run<D>(
    _title: &str,
    _elevation: bool,
    _setup: impl FnOnce(&Gpu) -> Result<D, String>,
    _draw: impl FnMut(&Gpu, &D, Orbit) -> Result<RgbaImage, String>,
) -> Result<(), WindowError> {
    Err(WindowError::NotBuilt)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_display_is_a_typed_error() {
        let none = |_: &str| None;
        let empty = |_: &str| Some(String::new());
        let x11 = |k: &str| (k == "DISPLAY").then(|| ":0".to_string());
        let wayland = |k: &str| (k == "WAYLAND_DISPLAY").then(|| "wayland-0".to_string());
        if cfg!(all(
            unix,
            not(target_os = "macos"),
            not(target_os = "android")
        )) {
            assert!(matches!(check_display(none), Err(WindowError::NoDisplay)));
            assert!(matches!(check_display(empty), Err(WindowError::NoDisplay)));
            let msg = check_display(none).unwrap_err().to_string();
            assert!(
                msg.contains("no display: set DISPLAY or WAYLAND_DISPLAY"),
                "{msg}"
            );
        }
        assert!(check_display(x11).is_ok());
        assert!(check_display(wayland).is_ok());
    }

    /// Built without the `window` feature (the default), opening the window is a typed error
    /// naming the feature; with it, on a machine without a display (this project's CI), the
    /// typed error comes before winit is touched.
    #[test]
    fn run_without_the_feature_or_a_display_is_a_typed_error() {
        let r = run(
            "test",
            false,
            |_| Ok(()),
            |_, _, _| Err("never drawn".to_string()),
        );
        if !cfg!(feature = "window") {
            assert!(matches!(r, Err(WindowError::NotBuilt)), "{r:?}");
            assert!(r.unwrap_err().to_string().contains("--features window"));
            return;
        }
        if check_display(|k| std::env::var(k).ok()).is_ok() {
            eprintln!("skipped: a display is set; the window would open");
            return;
        }
        assert!(matches!(r, Err(WindowError::NoDisplay)), "{r:?}");
    }
}
