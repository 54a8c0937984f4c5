//! A scene file's `fill` whose lattice would exceed the bound of generated meshes
//! (`MAX_GENERATED_VERTICES`) is refused before the mesher allocates it: measured with a counting
//! global allocator (process-wide: this file holds one test, so no other test allocates meanwhile).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use hooke_sim::file::{load_scene, SceneFileError, MAX_GENERATED_VERTICES};

struct Counting;

static BYTES: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        BYTES.fetch_add(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        BYTES.fetch_add(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_fill_above_the_bound_is_refused_before_it_allocates() {
    let dir = std::env::temp_dir().join(format!("hooke-fill-bound-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cube = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/meshes/cube.obj");
    let scene = |spacing: f64| {
        format!(
            "[mesh]\nfile = {:?}\nfill = {{ spacing = {spacing} }}\nstiffness = 1e4\n\
             mass = {{ density = 1000.0 }}\n\n[integrator]\nmethod = \"newton\"\n\
             time_step = 0.01\n\n[run]\nsteps = 1\n",
            cube.canonicalize().unwrap()
        )
    };
    // A 1 m cube at 4 mm: 254 lattice cubes a side with the padding, 255³ + 254³ ≈ 3.3e7 lattice
    // vertices, twice the bound (2^24 ≈ 1.7e7) but within the mesher's own default limit (2e8),
    // which would have filled it: about 30 M vertices and, with springs and a solver's matrices,
    // tens of GB.
    let path = dir.join("too-fine.toml");
    std::fs::write(&path, scene(0.004)).unwrap();
    let before = BYTES.load(Ordering::SeqCst);
    let result = load_scene(&path);
    let allocated = BYTES.load(Ordering::SeqCst) - before;
    let err = match result {
        Err(e) => e,
        Ok(_) => panic!("a fill of 3.3e7 lattice vertices was accepted"),
    };
    let SceneFileError::Invalid { key, reason, .. } = &err else {
        panic!("{err:?}");
    };
    assert_eq!(key, "mesh.fill");
    for part in [
        "needs 32968439 lattice vertices",
        &format!("limit of {MAX_GENERATED_VERTICES}"),
        "spacing",
    ] {
        assert!(reason.contains(part), "{part:?} not in {reason:?}");
    }
    // Reading the file and the cube's 300 faces takes a few hundred KB at most; the lattice's
    // signs alone would be 33 MB (one byte per vertex), its cut points and tetrahedra far more.
    assert!(
        allocated < 8 << 20,
        "{allocated} bytes allocated before the refusal"
    );
    std::fs::remove_dir_all(&dir).ok();
}
