//! `preview.png` is a picture of the lit scene, `atlas.png` the first atlas page (docs/contract.md,
//! "preview.png"): both written by `wavrad solve`, the preview from the file's camera when it has
//! one, else framing the scene.

use glam::DVec3;
use serde_json::Value;
use std::path::Path;
use wavrad::scene::gltf_writer::SceneBuilder;
use wavrad::scene::Camera;

mod common;
use common::cli::solve_ok;

/// An 8-bit RGB PNG: width, height, bytes.
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let decoder = png::Decoder::new(std::io::BufReader::new(file));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png data");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

fn solve(scene: &Path, out: &Path) -> Value {
    solve_ok(scene, out, &["--order", "1"]);
    serde_json::from_slice(&std::fs::read(out.join("result.json")).unwrap()).unwrap()
}

const GREY: [u8; 3] = [128, 128, 128];

/// The Cornell box carries a camera (aspect 1): the preview is its view into the box, not the atlas.
#[test]
fn the_cornell_box_preview_is_a_view_not_the_atlas() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("wavrad-preview-cornell-{}", std::process::id()));
    let result = solve(&root.join("scenes/cornell_box/cornell_box.gltf"), &out);
    let (aw, ah, atlas) = read_png(&out.join("atlas.png"));
    let page = &result["atlas"]["pages"][0];
    assert_eq!(
        (aw as u64, ah as u64),
        (
            page["width"].as_u64().unwrap(),
            page["height"].as_u64().unwrap()
        )
    );
    let (w, h, preview) = read_png(&out.join("preview.png"));
    assert_eq!((w, h), (640, 640));
    assert!((w, h) != (aw, ah) || preview != atlas);
    let px = |x: u32, y: u32| {
        let k = 3 * (y * w + x) as usize;
        [preview[k], preview[k + 1], preview[k + 2]]
    };
    // The camera looks into the box: its centre is lit surface, and most of the picture is.
    assert_ne!(px(w / 2, h / 2), GREY);
    let surface = (0..w * h).filter(|k| px(k % w, k / w) != GREY).count() as f64 / (w * h) as f64;
    println!("cornell box preview: {:.0} % surface", 100.0 * surface);
    assert!(
        surface > 0.5,
        "the box fills {:.0} % of the image",
        100.0 * surface
    );
    let _ = std::fs::remove_dir_all(&out);
}

fn lit_box() -> SceneBuilder {
    let mut b = SceneBuilder::new();
    let w = b.material([0.5; 3], [0.0; 3], false);
    let e = b.material([0.5; 3], [1.0; 3], false);
    b.inward_box([w, w, w, e, w, w], DVec3::ZERO, DVec3::ONE, 1);
    b
}

/// Without a camera the preview frames the scene (4:3): a closed box seen from outside shows its
/// inside (its near walls are culled), and the image's corners are background.
#[test]
fn without_a_camera_the_preview_frames_the_scene() {
    let dir = std::env::temp_dir().join(format!("wavrad-preview-frame-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("box.glb");
    std::fs::write(&scene, lit_box().to_glb()).unwrap();
    solve(&scene, &dir.join("out"));
    let (w, h, preview) = read_png(&dir.join("out/preview.png"));
    assert_eq!((w, h), (640, 480));
    let px = |x: u32, y: u32| {
        let k = 3 * (y * w + x) as usize;
        [preview[k], preview[k + 1], preview[k + 2]]
    };
    for (x, y) in [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1)] {
        assert_eq!(px(x, y), GREY, "corner ({x}, {y})");
    }
    // The centre sees the far walls' lit inside, not a wall's unlit back.
    let centre = px(w / 2, h / 2);
    assert!(
        centre != GREY && centre.iter().all(|&c| c > 0),
        "{centre:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A camera inside a closed box looking at its lit floor: the picture has the camera's aspect
/// and sees only surface.
#[test]
fn the_preview_uses_the_files_camera() {
    let dir = std::env::temp_dir().join(format!("wavrad-preview-camera-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut b = lit_box();
    b.camera(Camera {
        position: DVec3::new(0.5, 0.6, 0.5),
        forward: DVec3::NEG_Y,
        up: DVec3::Z,
        yfov: 1.2,
        aspect: Some(2.0),
        znear: 0.01,
    });
    let scene = dir.join("box.glb");
    std::fs::write(&scene, b.to_glb()).unwrap();
    solve(&scene, &dir.join("out"));
    let (w, h, preview) = read_png(&dir.join("out/preview.png"));
    assert_eq!((w, h), (640, 320));
    assert!(
        preview.chunks(3).all(|p| p != GREY),
        "inside the box every pixel sees a wall"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
