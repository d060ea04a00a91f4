//! `preview.png`: a picture of the lit scene, rendered from a camera.
//!
//! The camera is the glTF file's first perspective camera (`Scene::camera`), else one that frames
//! the scene ([`framing_camera`]: the bounding sphere of the faces that do not emit,
//! [`subject_bounds`], seen whole from a raised diagonal). One ray per
//! pixel centre is traced against every face (a BVH of its own over the faces' triangulations: the
//! solver's visibility BVH leaves out the faces that bound the scene). Back faces of single-sided
//! faces are culled, as engines do, so a closed room seen from outside shows its inside. The hit
//! is evaluated by the probes' rule (`probes::value_at_point`, among the hit face's roots, on the
//! side facing the camera), exposed like the atlas picture (the 99th percentile of the lit
//! pixels' luminance at 0.9), sRGB-encoded; pixels that see no face are [`BACKGROUND`].
//!
//! Invariants: the picture is a function of the solution, the faces and the camera (no sampling
//! noise: one ray through each pixel centre); rendering never changes the solution. Tests in this
//! module pin the framing (`framing_keeps_every_bounds_corner_in_the_image`), the pixel under a
//! face's centre (`the_pixel_under_a_lit_face_is_its_tone_mapped_solution`) and occlusion and
//! culling (`a_face_behind_another_is_hidden_and_back_faces_are_culled`).

use super::probes::value_at_point;
use super::{encode_rgb_png, preview_scale, srgb8};
use crate::pipeline::Prepared;
use crate::scene::{Bounds, Camera, Scene};
use crate::solver::visibility::intersect;
use crate::solver::Solution;
use glam::{DVec2, DVec3, Vec3A};
use obvhs::{aabb::Aabb, cwbvh::CwBvh, ray::Ray, ray::RayHit, Boundable, BvhBuildParams};
use rayon::prelude::*;

/// Pixels on the long side of the picture.
pub const PREVIEW_LONG_SIDE: u32 = 640;
/// Width over height when the camera does not say.
pub const DEFAULT_ASPECT: f64 = 4.0 / 3.0;
/// Vertical field of view of the framing camera, radians (45 degrees).
pub const FRAMING_YFOV: f64 = std::f64::consts::FRAC_PI_4;
/// The direction from the scene's centre to the framing camera (glTF is +Y up): raised and on a
/// diagonal, so that three sides of a box are in view.
pub const FRAMING_DIRECTION: [f64; 3] = [1.0, 0.8, 1.3];
/// sRGB value of a pixel that sees no face: a neutral grey.
pub const BACKGROUND: [u8; 3] = [128, 128, 128];
/// Boxes of the preview BVH are padded by this fraction of the scene diagonal (f32 boxes).
const BOX_PADDING_REL: f64 = 1e-5;

/// A camera that frames `bounds` for an image of width over height `aspect`: it looks at the
/// bounds' centre from [`FRAMING_DIRECTION`], far enough for the whole bounding sphere to lie in
/// the view cone inscribed in the image (so every corner of the bounds projects inside it).
pub fn framing_camera(bounds: &Bounds, aspect: f64) -> Camera {
    let centre = if bounds.min.x <= bounds.max.x {
        0.5 * (bounds.min + bounds.max)
    } else {
        DVec3::ZERO
    };
    let radius = (0.5 * bounds.diagonal()).max(1e-9);
    let half_y = 0.5 * FRAMING_YFOV;
    let half_x = (half_y.tan() * aspect).atan();
    // A 5 % margin around the sphere.
    let distance = 1.05 * radius / half_y.min(half_x).sin();
    let back = DVec3::from(FRAMING_DIRECTION).normalize();
    let forward = -back;
    let up = (DVec3::Y - forward * DVec3::Y.dot(forward)).normalize();
    Camera {
        position: centre + back * distance,
        forward,
        up,
        yfov: FRAMING_YFOV,
        aspect: Some(aspect),
        znear: 0.0,
    }
}

/// The picture's size for a camera: [`PREVIEW_LONG_SIDE`] on the long side, the camera's aspect
/// (or [`DEFAULT_ASPECT`]).
pub fn image_size(camera: &Camera) -> (u32, u32) {
    let aspect = camera
        .aspect
        .unwrap_or(DEFAULT_ASPECT)
        .clamp(1.0 / 16.0, 16.0);
    let long = PREVIEW_LONG_SIDE as f64;
    if aspect >= 1.0 {
        (PREVIEW_LONG_SIDE, ((long / aspect).round() as u32).max(1))
    } else {
        (((long * aspect).round() as u32).max(1), PREVIEW_LONG_SIDE)
    }
}

/// A camera's view of a `width` x `height` image (square pixels: the horizontal field of view
/// follows from the vertical one and the image's own aspect).
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    right: DVec3,
    tan_x: f64,
    tan_y: f64,
}

impl View {
    pub fn new(camera: Camera, width: u32, height: u32) -> View {
        let tan_y = (0.5 * camera.yfov).tan();
        View {
            camera,
            width,
            height,
            right: camera.forward.cross(camera.up).normalize(),
            tan_x: tan_y * width as f64 / height as f64,
            tan_y,
        }
    }

    /// Unit direction of the ray through image point `p` (pixels, `(0, 0)` the top-left corner).
    pub fn ray(&self, p: DVec2) -> DVec3 {
        let x = (2.0 * p.x / self.width as f64 - 1.0) * self.tan_x;
        let y = (1.0 - 2.0 * p.y / self.height as f64) * self.tan_y;
        (self.camera.forward + self.right * x + self.camera.up * y).normalize()
    }

    /// Image point (pixels) of world point `x`; `None` behind the camera.
    pub fn project(&self, x: DVec3) -> Option<DVec2> {
        let q = x - self.camera.position;
        let z = q.dot(self.camera.forward);
        if z <= 0.0 {
            return None;
        }
        let sx = q.dot(self.right) / z / self.tan_x;
        let sy = q.dot(self.camera.up) / z / self.tan_y;
        Some(DVec2::new(
            0.5 * (sx + 1.0) * self.width as f64,
            0.5 * (1.0 - sy) * self.height as f64,
        ))
    }
}

/// One triangle of a face, with what culling needs.
#[derive(Debug, Clone, Copy)]
struct Tri {
    vertices: [DVec3; 3],
    face: u32,
    normal: DVec3,
    double_sided: bool,
    aabb: Aabb,
}

impl Boundable for Tri {
    fn aabb(&self) -> Aabb {
        self.aabb
    }
}

/// Every face's triangles in a BVH, for closest hits.
struct Faces {
    tris: Vec<Tri>,
    bvh: Option<CwBvh>,
}

impl Faces {
    fn new(prepared: &Prepared) -> Faces {
        let pad = (BOX_PADDING_REL * prepared.diagonal).max(f64::MIN_POSITIVE) as f32;
        let tris: Vec<Tri> = prepared
            .faces
            .faces
            .iter()
            .flat_map(|f| {
                f.triangulation.iter().map(move |v| Tri {
                    vertices: *v,
                    face: f.id.0,
                    normal: f.normal,
                    double_sided: f.double_sided,
                    aabb: Aabb::new(
                        v[0].min(v[1]).min(v[2]).as_vec3a() - Vec3A::splat(pad),
                        v[0].max(v[1]).max(v[2]).as_vec3a() + Vec3A::splat(pad),
                    ),
                })
            })
            .collect();
        let bvh = (!tris.is_empty()).then(|| {
            obvhs::cwbvh::builder::build_cwbvh(
                &tris,
                BvhBuildParams::medium_build(),
                &mut std::time::Duration::default(),
            )
        });
        Faces { tris, bvh }
    }

    /// The closest triangle the ray `origin + t dir` (`t > tmin`) meets on a side it may see: the
    /// ray parameter and the triangle.
    fn closest(&self, origin: DVec3, dir: DVec3, tmin: f64) -> Option<(f64, &Tri)> {
        let bvh = self.bvh.as_ref()?;
        let mut best: Option<(f64, usize)> = None;
        let ray = Ray::new_inf(origin.as_vec3a(), dir.as_vec3a());
        let mut hit = RayHit::none();
        bvh.ray_traverse(ray, &mut hit, |_, id| {
            let k = bvh.primitive_indices[id] as usize;
            let tri = &self.tris[k];
            // A single-sided face seen from behind is culled.
            if !tri.double_sided && dir.dot(tri.normal) >= 0.0 {
                return f32::INFINITY;
            }
            match intersect(origin, dir, &tri.vertices) {
                Some(t) if t > tmin && best.is_none_or(|b| t < b.0) => {
                    best = Some((t, k));
                    // Rounded up, so the f32 traversal never prunes a nearer hit.
                    (t * (1.0 + 1e-6)) as f32 + f32::MIN_POSITIVE
                }
                _ => f32::INFINITY,
            }
        });
        best.map(|(t, k)| (t, &self.tris[k]))
    }
}

/// A rendered picture before tone mapping: per pixel, row-major from the top, the solution at the
/// surface the pixel sees (`None` where it sees no face).
#[derive(Debug, Clone)]
pub struct Render {
    pub view: View,
    pub pixels: Vec<Option<[f64; 3]>>,
}

/// Renders the solution through `view`.
pub fn render(prepared: &Prepared, solution: &Solution, view: &View) -> Render {
    let faces = Faces::new(prepared);
    let mut roots_of_face: Vec<Vec<usize>> = vec![Vec::new(); prepared.faces.faces.len()];
    for s in &prepared.surfaces {
        if let Some(list) = roots_of_face.get_mut(s.face.0 as usize) {
            list.extend(s.roots.clone());
        }
    }
    let camera = &view.camera;
    let (w, h) = (view.width as usize, view.height as usize);
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|k| {
            let p = DVec2::new((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
            let dir = view.ray(p);
            // The near plane, along this ray.
            let tmin = camera.znear / dir.dot(camera.forward).max(1e-12);
            let (t, tri) = faces.closest(camera.position, dir, tmin)?;
            let x = camera.position + dir * t;
            let side = if dir.dot(tri.normal) < 0.0 {
                tri.normal
            } else {
                -tri.normal
            };
            let roots = roots_of_face
                .get(tri.face as usize)
                .map(Vec::as_slice)
                .unwrap_or_default();
            let value = value_at_point(
                solution,
                roots.iter().copied(),
                x,
                side,
                f64::INFINITY,
                prepared.diagonal,
            );
            Some(value.l.unwrap_or([0.0; 3]))
        })
        .collect();
    Render {
        view: *view,
        pixels,
    }
}

impl Render {
    /// The exposure: the atlas picture's rule over the pixels that see a face.
    pub fn exposure(&self) -> f32 {
        let lit: Vec<[f32; 4]> = self
            .pixels
            .iter()
            .flatten()
            .map(|v| [v[0] as f32, v[1] as f32, v[2] as f32, 1.0])
            .collect();
        preview_scale(&lit)
    }

    /// The sRGB bytes of every pixel, row-major from the top.
    pub fn to_srgb(&self) -> Vec<u8> {
        let scale = self.exposure();
        let mut data = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            match p {
                Some(v) => data.extend(v.map(|c| srgb8(c as f32 * scale))),
                None => data.extend(BACKGROUND),
            }
        }
        data
    }

    /// The PNG file.
    pub fn to_png(&self) -> std::io::Result<Vec<u8>> {
        encode_rgb_png(&self.to_srgb(), self.view.width, self.view.height)
    }
}

/// What the framing camera frames: the bounds of the faces that do not emit, else of the scene. A
/// sky panel over a lit model (seen from above, its single-sided face is culled) would otherwise
/// shrink the model to a few pixels.
pub fn subject_bounds(scene: &Scene, prepared: &Prepared) -> Bounds {
    let mut bounds = Bounds::empty();
    for f in &prepared.faces.faces {
        if scene
            .materials
            .get(f.material as usize)
            .is_some_and(|m| !m.is_emissive())
        {
            for v in f.triangulation.iter().flatten() {
                bounds.extend(*v);
            }
        }
    }
    if bounds.min.x <= bounds.max.x {
        bounds
    } else {
        scene.bounds
    }
}

/// `preview.png` of a solved scene: from the scene's camera, else [`framing_camera`] of the
/// [`subject_bounds`].
pub fn preview_png(
    scene: &Scene,
    prepared: &Prepared,
    solution: &Solution,
) -> std::io::Result<Vec<u8>> {
    let camera = scene
        .camera
        .unwrap_or_else(|| framing_camera(&subject_bounds(scene, prepared), DEFAULT_ASPECT));
    let (width, height) = image_size(&camera);
    render(prepared, solution, &View::new(camera, width, height)).to_png()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_keeps_every_bounds_corner_in_the_image() {
        let boxes = [
            (DVec3::new(-1.0, 0.0, -1.0), DVec3::new(1.0, 2.0, 1.0)),
            (DVec3::new(10.0, -3.0, 5.0), DVec3::new(200.0, 1.0, 6.0)),
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.1, 30.0, 0.1)),
        ];
        for (min, max) in boxes {
            let bounds = Bounds { min, max };
            for aspect in [DEFAULT_ASPECT, 0.5, 3.0] {
                let camera = framing_camera(&bounds, aspect);
                let (w, h) = image_size(&camera);
                assert!(((w as f64 / h as f64) - aspect).abs() < 0.01);
                let view = View::new(camera, w, h);
                for k in 0..8 {
                    let corner = DVec3::new(
                        if k & 1 == 0 { min.x } else { max.x },
                        if k & 2 == 0 { min.y } else { max.y },
                        if k & 4 == 0 { min.z } else { max.z },
                    );
                    let p = view.project(corner).expect("in front of the camera");
                    assert!(
                        p.x > 0.0 && p.x < w as f64 && p.y > 0.0 && p.y < h as f64,
                        "corner {corner} of {min}..{max} projects to {p} outside {w} x {h}"
                    );
                }
                // The camera looks at the centre from above (+Y up).
                let centre = view.project(0.5 * (min + max)).expect("centre");
                assert!((centre - DVec2::new(w as f64, h as f64) * 0.5).length() < 1e-6);
                assert!(camera.position.y > 0.5 * (min.y + max.y));
            }
        }
    }

    #[test]
    fn a_ray_through_a_projected_point_comes_back_to_it() {
        let bounds = Bounds {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        };
        let view = View::new(framing_camera(&bounds, 1.5), 300, 200);
        for p in [DVec2::new(10.5, 20.5), DVec2::new(150.0, 100.0)] {
            let x = view.camera.position + view.ray(p) * 3.0;
            let q = view.project(x).expect("in front");
            assert!((q - p).length() < 1e-9, "{p} -> {q}");
        }
    }

    /// Renders `glb` solved with default parameters through `camera` at `w x h`.
    fn solve_and_render(glb: &[u8], camera: Camera, w: u32, h: u32) -> (Solution, f64, Render) {
        use crate::scene::{load_scene, ExternalFiles};
        let scene = load_scene(glb, &ExternalFiles::Refuse, 1_000_000).expect("scene loads");
        let (prepared, solution) = crate::pipeline::bake(
            &scene,
            crate::domain::DomainMode::Extended,
            crate::solver::SolverParams::default(),
            &std::sync::atomic::AtomicBool::new(false),
            &mut |_| {},
        )
        .expect("solves");
        let render = render(&prepared, &solution, &View::new(camera, w, h));
        (solution, prepared.diagonal, render)
    }

    /// The solution at a point of a face seen from side `n`, as a probe reads it.
    fn probe(solution: &Solution, diagonal: f64, x: DVec3, n: DVec3) -> [f64; 3] {
        let pr = super::super::probes::ProbePoint {
            p: x.to_array(),
            n: n.to_array(),
        };
        super::super::probes::evaluate_probes(solution, &[pr], diagonal)[0]
            .l
            .expect("the probe finds its face")
    }

    /// A lit face A (z = 0, [0,1]^2, facing the camera), an emitting panel C behind it (z = -1,
    /// [-1,2]^2) and a single-sided square D (z = 1, [0,0.3]^2) between the camera and A, facing
    /// away from the camera; a point light lights them. The camera looks straight down -Z at A's
    /// centre; the image is 101 x 101, so the middle pixel's ray goes through A's centre.
    fn three_panels() -> (Vec<u8>, Camera) {
        use crate::scene::gltf_writer::SceneBuilder;
        use crate::scene::{LightKind, PunctualLight};
        let mut b = SceneBuilder::new();
        let a = b.material([0.5, 0.6, 0.7], [0.0; 3], false);
        let c = b.material([0.3; 3], [1.0, 0.9, 0.8], false);
        let d = b.material([0.8; 3], [0.0; 3], false);
        b.quad(a, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
        b.quad(
            c,
            DVec3::new(-1.0, -1.0, -1.0),
            DVec3::X * 3.0,
            DVec3::Y * 3.0,
            1,
        );
        // u x v = Y x X = -Z: D faces away from the camera.
        b.quad(
            d,
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::Y * 0.3,
            DVec3::X * 0.3,
            1,
        );
        b.light(PunctualLight {
            name: "bulb".into(),
            kind: LightKind::Point {
                position: DVec3::new(0.5, 0.5, 2.0),
            },
            intensity: [4.0; 3],
        });
        let camera = Camera {
            position: DVec3::new(0.5, 0.5, 5.0),
            forward: DVec3::NEG_Z,
            up: DVec3::Y,
            // C's half-width seen from 6 m is 1.5 m: the view (2 m at C) reaches past it.
            yfov: 2.0 * (2.0f64 / 6.0).atan(),
            aspect: Some(1.0),
            znear: 0.01,
        };
        (b.to_glb(), camera)
    }

    /// The pixel whose ray passes through world point `x`, and the point where that pixel's ray
    /// meets the plane `z = z0`.
    fn pixel_through(view: &View, x: DVec3, z0: f64) -> (usize, DVec3) {
        let p = view.project(x).expect("in front").floor();
        let dir = view.ray(p + DVec2::splat(0.5));
        let t = (z0 - view.camera.position.z) / dir.z;
        (
            p.y as usize * view.width as usize + p.x as usize,
            view.camera.position + dir * t,
        )
    }

    #[test]
    fn the_pixel_under_a_lit_face_is_its_tone_mapped_solution() {
        let (glb, camera) = three_panels();
        let (solution, diagonal, render) = solve_and_render(&glb, camera, 101, 101);
        let srgb = render.to_srgb();
        let exposure = render.exposure();
        let byte = |k: usize| [srgb[3 * k], srgb[3 * k + 1], srgb[3 * k + 2]];
        // The middle pixel sees A's centre: the probe there, tone-mapped.
        let middle = 50 * 101 + 50;
        let a = probe(&solution, diagonal, DVec3::new(0.5, 0.5, 0.0), DVec3::Z);
        assert!(a.iter().all(|&c| c > 0.0), "A is lit: {a:?}");
        let seen = render.pixels[middle].expect("the middle pixel sees A");
        for c in 0..3 {
            assert!(
                (seen[c] - a[c]).abs() <= 1e-12 * a[c].max(1.0),
                "{seen:?} vs {a:?}"
            );
        }
        assert_eq!(byte(middle), a.map(|c| srgb8(c as f32 * exposure)));
        // Off the scene: the image's corners see past C.
        for k in [0, 100, 100 * 101, 101 * 101 - 1] {
            assert_eq!(render.pixels[k], None);
            assert_eq!(byte(k), BACKGROUND);
        }
        // The PNG holds those bytes.
        let png = render.to_png().expect("encodes");
        let decoder = png::Decoder::new(std::io::Cursor::new(png));
        let mut reader = decoder.read_info().expect("png header");
        let mut buf = vec![0; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut buf).expect("png data");
        assert_eq!((info.width, info.height), (101, 101));
        assert_eq!(&buf[..info.buffer_size()], &srgb[..]);
    }

    #[test]
    fn a_face_behind_another_is_hidden_and_back_faces_are_culled() {
        let (glb, camera) = three_panels();
        let (solution, diagonal, render) = solve_and_render(&glb, camera, 101, 101);
        let view = render.view;
        // C, beside A: the pixel shows C (emitting), where its ray meets C.
        let (k, hit) = pixel_through(&view, DVec3::new(1.75, 0.5, -1.0), -1.0);
        let c = probe(&solution, diagonal, hit, DVec3::Z);
        let seen = render.pixels[k].expect("sees C");
        assert!(c[0] > 1.0 / std::f64::consts::PI, "C emits: {c:?}");
        assert!((0..3).all(|i| (seen[i] - c[i]).abs() <= 1e-12 * c[i].max(1.0)));
        // A's centre hides C: the middle pixel is A's value, far below C's.
        let middle = render.pixels[50 * 101 + 50].expect("sees A");
        assert!(middle[0] < 0.5 * c[0], "A {middle:?} hides C {c:?}");
        // Through D's back (single-sided, facing away): D is culled, the pixel shows A.
        let (k, hit) = pixel_through(&view, DVec3::new(0.2, 0.2, 0.0), 0.0);
        let through_d = DVec3::new(0.5, 0.5, 5.0) + (hit - DVec3::new(0.5, 0.5, 5.0)) * 0.8;
        assert!(through_d.x < 0.3 && through_d.y < 0.3, "the ray crosses D");
        let a = probe(&solution, diagonal, hit, DVec3::Z);
        let seen = render.pixels[k].expect("sees A through D's back");
        assert!(a[0] > 0.0);
        assert!((0..3).all(|i| (seen[i] - a[i]).abs() <= 1e-12 * a[i].max(1.0)));
    }

    /// A sky panel (an emitter far larger than the model under it) is left out of what the
    /// framing camera frames; a scene whose every face emits is framed whole.
    #[test]
    fn the_framing_leaves_out_emitters() {
        use crate::scene::gltf_writer::SceneBuilder;
        use crate::scene::{load_scene, ExternalFiles};
        let mut b = SceneBuilder::new();
        let model = b.material([0.5; 3], [0.0; 3], false);
        let sky = b.material([0.0; 3], [1.0; 3], false);
        b.quad(model, DVec3::ZERO, DVec3::X, DVec3::Z * -1.0, 1);
        b.quad(
            sky,
            DVec3::new(-50.0, 10.0, 50.0),
            DVec3::Z * -100.0,
            DVec3::X * 100.0,
            1,
        );
        let scene = load_scene(&b.to_glb(), &ExternalFiles::Refuse, 1000).expect("loads");
        let prepared = crate::pipeline::prepare(&scene, crate::domain::DomainMode::Extended);
        let bounds = subject_bounds(&scene, &prepared);
        assert!(
            (bounds.min - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-9,
            "{bounds:?}"
        );
        assert!(
            (bounds.max - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-9,
            "{bounds:?}"
        );
        let mut b = SceneBuilder::new();
        let sky = b.material([0.0; 3], [1.0; 3], false);
        b.quad(sky, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
        let scene = load_scene(&b.to_glb(), &ExternalFiles::Refuse, 1000).expect("loads");
        let prepared = crate::pipeline::prepare(&scene, crate::domain::DomainMode::Extended);
        assert_eq!(subject_bounds(&scene, &prepared), scene.bounds);
    }
}
