//! The real window under a virtual X server: Xvfb is started on a free display, the editor's
//! minifb window opens on it, XTest presses space (pause) and clicks, and the frame is read back
//! from the X server with XGetImage: the new particle is drawn where the click was. The session is
//! recorded (`record_path`), and the recording replays to the editor's final state.
//!
//! Needs the `window` feature (on in `cargo test --workspace`, through hooke-cli) and the `Xvfb`
//! program. Without Xvfb the test says so and passes, unless `HOOKE_REQUIRE_XVFB` is set, as
//! `.ci/run` sets it after installing Xvfb: then a missing Xvfb fails.
#![cfg(all(feature = "window", target_os = "linux"))]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use hooke_editor::window::{run, WindowSettings};
use hooke_editor::{Editor, EditorParams, Script};
use x11_dl::{keysym, xlib, xtest};

const SIZE: u32 = 256;

struct Server(Child);

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn xvfb_available() -> bool {
    Command::new("Xvfb")
        .arg("-help")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

/// Start Xvfb on the first free display from :71, with a screen the window's size (so that the
/// window, centred, sits at (0, 0)).
fn start_server() -> (Server, String) {
    for number in 71..100 {
        if Path::new(&format!("/tmp/.X11-unix/X{number}")).exists()
            || Path::new(&format!("/tmp/.X{number}-lock")).exists()
        {
            continue;
        }
        let child = Command::new("Xvfb")
            .arg(format!(":{number}"))
            .args([
                "-screen",
                "0",
                &format!("{SIZE}x{SIZE}x24"),
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb starts");
        let server = Server(child);
        let socket = format!("/tmp/.X11-unix/X{number}");
        let start = Instant::now();
        while !Path::new(&socket).exists() {
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "Xvfb :{number} did not come up"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        return (server, format!(":{number}"));
    }
    panic!("no free X display between :71 and :99");
}

struct Client {
    xlib: xlib::Xlib,
    xtest: xtest::Xf86vmode,
    display: *mut xlib::Display,
}

impl Client {
    fn open(name: &str) -> Client {
        let xlib = xlib::Xlib::open().expect("libX11 loads");
        let xtest = xtest::Xf86vmode::open().expect("libXtst loads");
        let name = std::ffi::CString::new(name).unwrap();
        let display = unsafe { (xlib.XOpenDisplay)(name.as_ptr()) };
        assert!(!display.is_null(), "cannot connect to the virtual X server");
        Client {
            xlib,
            xtest,
            display,
        }
    }

    /// The screen's pixel at (x, y), 0xRRGGBB.
    fn pixel(&self, x: i32, y: i32) -> u32 {
        unsafe {
            let root = (self.xlib.XDefaultRootWindow)(self.display);
            let image = (self.xlib.XGetImage)(self.display, root, x, y, 1, 1, !0, xlib::ZPixmap);
            assert!(!image.is_null(), "XGetImage failed");
            let value = (self.xlib.XGetPixel)(image, 0, 0) as u32 & 0xFF_FFFF;
            if let Some(destroy) = (*image).funcs.destroy_image {
                destroy(image);
            }
            value
        }
    }

    fn key(&self, symbol: u32) {
        unsafe {
            let code = (self.xlib.XKeysymToKeycode)(self.display, u64::from(symbol));
            (self.xtest.XTestFakeKeyEvent)(self.display, u32::from(code), 1, 0);
            (self.xlib.XFlush)(self.display);
            std::thread::sleep(Duration::from_millis(150));
            (self.xtest.XTestFakeKeyEvent)(self.display, u32::from(code), 0, 0);
            (self.xlib.XFlush)(self.display);
        }
    }

    fn click(&self, x: i32, y: i32) {
        unsafe {
            (self.xtest.XTestFakeMotionEvent)(self.display, 0, x, y, 0);
            (self.xlib.XFlush)(self.display);
            std::thread::sleep(Duration::from_millis(150));
            (self.xtest.XTestFakeButtonEvent)(self.display, 1, 1, 0);
            (self.xlib.XFlush)(self.display);
            std::thread::sleep(Duration::from_millis(150));
            (self.xtest.XTestFakeButtonEvent)(self.display, 1, 0, 0);
            (self.xlib.XFlush)(self.display);
        }
    }

    fn wait_for(&self, what: &str, mut condition: impl FnMut(&Client) -> bool) {
        let start = Instant::now();
        while !condition(self) {
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "timed out waiting for {what}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Client {
    fn drop(&mut self) {
        unsafe { (self.xlib.XCloseDisplay)(self.display) };
    }
}

fn dark(pixel: u32) -> bool {
    let [r, g, b] = [(pixel >> 16) & 0xFF, (pixel >> 8) & 0xFF, pixel & 0xFF];
    r < 0x40 && g < 0x40 && b < 0x40
}

#[test]
fn the_window_shows_a_clicked_particle() {
    if !xvfb_available() {
        assert!(
            std::env::var_os("HOOKE_REQUIRE_XVFB").is_none(),
            "HOOKE_REQUIRE_XVFB is set but Xvfb is not installed"
        );
        eprintln!("skipped: Xvfb is not installed (CI installs it and sets HOOKE_REQUIRE_XVFB)");
        return;
    }
    let (_server, display) = start_server();
    std::env::set_var("DISPLAY", &display);
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("events.json");
    let record_path = recording.clone();
    let save_path = dir.path().join("edited.toml");
    let window = std::thread::spawn(move || {
        let mut editor = Editor::new(EditorParams::default()).unwrap();
        let settings = WindowSettings {
            size: SIZE,
            save_path,
            record_path: Some(record_path),
            max_frames: Some(3000),
            target_fps: 30,
        };
        let shown = run(&mut editor, &settings).expect("the window runs under Xvfb");
        (editor, shown)
    });
    let client = Client::open(&display);
    // The background (0xDDDDDD) in the lower half, below the overlay: the window is up.
    let (x, y) = (SIZE as i32 / 4, 3 * SIZE as i32 / 4);
    client.wait_for("the window's first frame", |c| c.pixel(x, y) == 0xDDDDDD);
    // The recording is written while the window runs, not only when it closes.
    client.wait_for("the recording's first write", |_| recording.exists());
    client.key(keysym::XK_space);
    client.click(x, y);
    client.wait_for("the clicked particle to be drawn", |c| dark(c.pixel(x, y)));
    client.key(keysym::XK_Escape);
    let (editor, shown) = window.join().expect("the window thread does not panic");
    assert!(shown < 3000, "Escape closed the window");
    assert!(editor.is_paused(), "space reached the editor");
    assert_eq!(editor.particle_count(), 1, "one click, one particle");
    let p = editor.positions()[0];
    // The click's pixel centre maps to (x + ½)/256 or x/256: within one pixel.
    assert!((p.x - 0.25).abs() <= 1.0 / SIZE as f64, "{p:?}");
    assert!((p.y - 0.25).abs() <= 1.0 / SIZE as f64, "{p:?}");
    // What the window received replays, headless, to the same state.
    let text = std::fs::read_to_string(&recording).unwrap();
    let script = serde_json::from_str::<Script>(&text)
        .unwrap()
        .validated()
        .unwrap();
    assert_eq!(
        script.frames as u64, shown,
        "one recorded frame per frame shown"
    );
    let mut replayed = Editor::new(EditorParams::default()).unwrap();
    script.replay(&mut replayed, |_, _, _| Ok(())).unwrap();
    assert_eq!(replayed.positions(), editor.positions(), "{text}");
    assert_eq!(replayed.velocities(), editor.velocities());
    assert_eq!(replayed.is_paused(), editor.is_paused());
    assert_eq!(replayed.frames(), editor.frames());
    assert_eq!(replayed.cursor(), editor.cursor());
}
