//! Sample scenes the service tests submit: lit boxes (converging or never converging), a single
//! emitting triangle as editable glTF JSON, and a cluttered room whose shots take long; and the
//! slab under a black box (14 triangles) of `tests/analytic.rs` and `tests/memory.rs`.

use glam::DVec3;
use serde_json::{json, Value};
use wavrad::scene::gltf_writer::SceneBuilder;

/// A unit box seen from inside, each side an `n x n` grid of quads, reflectance `rho`, the -x
/// wall emitting (L_e = 1).
pub fn box_scene(rho: f64, n: u32) -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let wall = b.material([rho; 3], [0.0; 3], false);
    let lamp = b.material([rho; 3], [1.0; 3], false);
    b.inward_box(
        [lamp, wall, wall, wall, wall, wall],
        DVec3::ZERO,
        DVec3::ONE,
        n,
    );
    b.to_glb()
}

/// A unit box seen from inside, one quad per side (12 triangles), reflectance `rho`, the -x wall
/// emitting.
pub fn small_scene(rho: f64) -> Vec<u8> {
    box_scene(rho, 1)
}

/// A closed box of white walls (rho = 1): no light is ever absorbed, so the solve never converges
/// and runs until cancelled or its time budget ends.
pub fn never_converging_scene() -> Vec<u8> {
    box_scene(1.0, 3)
}

/// One emitting triangle: the glTF JSON (its buffer has no URI yet) and the buffer's bytes,
/// positions (3 x VEC3 f32) then indices (3 x u32).
pub fn one_triangle_gltf(positions: [[f32; 3]; 3], indices: [u32; 3]) -> (Value, Vec<u8>) {
    let mut bin = Vec::new();
    for p in positions {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let root = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"emissiveFactor": [1.0, 1.0, 1.0]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12}
        ],
        "buffers": [{"byteLength": 48}]
    });
    (root, bin)
}

/// The corners of `one_triangle_gltf`'s usual triangle (half the unit square in z = 0).
pub const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// A room lit from its -x wall holding a `k x k` grid of small double-sided cubes at jittered
/// heights: thousands of non-coplanar faces, so one shot of order 3 takes long.
pub fn cluttered_scene(k: u32) -> Vec<u8> {
    let mut b = SceneBuilder::new();
    let wall = b.material([0.8; 3], [0.0; 3], false);
    let lamp = b.material([0.8; 3], [1.0; 3], false);
    let block = b.material([0.7; 3], [0.0; 3], true);
    let size = 10.0;
    b.inward_box(
        [lamp, wall, wall, wall, wall, wall],
        DVec3::ZERO,
        DVec3::splat(size),
        1,
    );
    let step = size / f64::from(k + 1);
    for i in 0..k {
        for j in 0..k {
            let h = 0.5 + 0.37 * f64::from((i * 7 + j * 13) % 11);
            let min = DVec3::new(step * f64::from(i + 1), step * f64::from(j + 1), h);
            let s = step * 0.4;
            let (x, y, z) = (DVec3::X * s, DVec3::Y * s, DVec3::Z * s);
            b.quad(block, min, y, z, 1);
            b.quad(block, min + x, y, z, 1);
            b.quad(block, min, z, x, 1);
            b.quad(block, min + y, z, x, 1);
            b.quad(block, min, x, y, 1);
            b.quad(block, min + z, x, y, 1);
        }
    }
    b.to_glb()
}

/// A 1 m slab (rho 1) with a black box (0.84 x 0.84 x 0.3 m) standing on its middle, under a
/// 4 x 4 m emitter (L_e = 1) 1 m above it, facing down: 14 triangles. Only the slab's border ring
/// is lit, by a large source split many times for its visibility (many links per node).
pub struct SlabUnderABox {
    pub glb: Vec<u8>,
    /// The slab's material.
    pub slab: u32,
    /// The box's corners.
    pub lo: DVec3,
    pub hi: DVec3,
}

pub fn slab_under_a_box() -> SlabUnderABox {
    let mut b = SceneBuilder::new();
    let slab = b.material([1.0; 3], [0.0; 3], false);
    let black = b.material([0.0; 3], [0.0; 3], false);
    let lamp = b.material([0.0; 3], [1.0; 3], false);
    let (x, y) = (DVec3::X, DVec3::Y);
    b.quad(slab, DVec3::new(-0.5, -0.5, 0.0), x, y, 1);
    let (lo, hi) = (DVec3::new(-0.42, -0.42, 0.0), DVec3::new(0.42, 0.42, 0.3));
    let (bx, by, bz) = (x * 0.84, y * 0.84, DVec3::Z * 0.3);
    b.quad(black, lo, bz, by, 1); // normal -x
    b.quad(black, lo + bx, by, bz, 1); // +x
    b.quad(black, lo, bx, bz, 1); // -y
    b.quad(black, lo + by, bz, bx, 1); // +y
    b.quad(black, lo + bz, bx, by, 1); // top, +z
    b.quad(lamp, DVec3::new(-2.0, -2.0, 1.0), y * 4.0, x * 4.0, 1); // facing -z
    SlabUnderABox {
        glb: b.to_glb(),
        slab,
        lo,
        hi,
    }
}

/// A cluttered room whose first shot (the lamp wall, at the tolerance of
/// `tests/progress.rs`'s `long_first_shot_params`: `order=1&tolerance=3e-8`) lasts seconds.
pub fn long_first_shot() -> Vec<u8> {
    cluttered_scene(8)
}
