//! Keeps a headless run's output free of a false alarm from the system's Vulkan stack.
//!
//! On a machine without a desktop session (`XDG_RUNTIME_DIR` unset, as over SSH, in CI or in a
//! container), Mesa's implicit Vulkan layer `VK_LAYER_MESA_device_select` asks libwayland for a
//! compositor when wgpu enumerates adapters (wgpu enables `VK_KHR_wayland_surface` on every
//! instance), and libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set in the
//! environment.` once per enumeration — although nothing failed and no window is wanted.

/// Without a session there is no display whose GPU the layer could prefer, so this switches
/// the layer off through its own documented variable, `NODEVICE_SELECT=1` — unless the user
/// set that variable or picked a device with `MESA_VK_DEVICE_SELECT`. Call it first thing in
/// `main`, before any thread starts (it sets a process environment variable); wgpu's own
/// adapter choice and `WGPU_ADAPTER_NAME` are unaffected.
pub fn quiet_display_probe() {
    let session = std::env::var_os("XDG_RUNTIME_DIR")
        .is_some_and(|dir| std::path::Path::new(&dir).is_absolute());
    let chosen = ["NODEVICE_SELECT", "MESA_VK_DEVICE_SELECT"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    if !session && !chosen {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}
