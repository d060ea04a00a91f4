//! Textures (issue 16): base colour and emissive textures read and solved with.
//!
//! - A textured twin of the Kenney building (one palette material, uniform cells of the original
//!   colours as sRGB bytes, each primitive's `TEXCOORD_0` inside its colour's cell; the sky
//!   panel's emission from an `emissiveTexture`) against the Monte Carlo reference: within 0.3
//!   points of the untextured scene's nrms, and their probe values within 1.5 % nrms of each
//!   other. The same with a factor of 0.7 times a texture, and with a JPEG texture.
//! - A face with a texture ramp (reflectance 0.2 to 0.8) under uniform irradiance: its reflected
//!   power, and what a black wall lit only by it receives, against brute-force integrals.
//! - Refusals: an image that cannot be decoded, a texture whose `TEXCOORD_n` is missing.
//!
//! Print the figures: `cargo test --release --test textures -- --nocapture`.

use glam::DVec3;
use serde_json::{json, Value};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use wavrad::domain::DomainMode;
use wavrad::output::probes::evaluate_probes;
use wavrad::pipeline::bake;
use wavrad::reference::ReferenceSet;
use wavrad::scene::gltf_writer::SceneBuilder;
use wavrad::scene::{load_scene, ExternalFiles, LightKind, PunctualLight, Scene, SceneError};
use wavrad::solver::{Quantity, SolverParams};

mod common;
use common::cli::wavrad;
use common::gltf::{glow, glowing_quad_gltf, linear_to_srgb_byte, palette_image, Glb};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// How a twin colours its surfaces.
#[derive(Clone, Copy)]
struct TwinStyle {
    format: image::ImageFormat,
    /// `baseColorFactor` of the shared palette material (the cells hold colour / factor).
    factor: f64,
    /// The sky's emission from an `emissiveTexture` (else its factor alone, as the original).
    emissive_texture: bool,
}

/// The textured twin of a scene whose primitives each use one untextured material: one palette
/// material for every non-emissive primitive, each primitive's `TEXCOORD_0` at its colour's cell
/// centre; emissive materials keep their own material (when asked, with an `emissiveTexture` of a
/// grey cell and the `emissiveStrength` that brings it back to the original emission).
fn textured_twin(original: &[u8], style: TwinStyle) -> Vec<u8> {
    let mut glb = Glb::parse(original);
    let materials = glb.json["materials"].as_array().unwrap().clone();
    let is_emissive = |m: &Value| {
        m["emissiveFactor"]
            .as_array()
            .is_some_and(|e| e.iter().any(|x| x.as_f64().unwrap_or(0.0) > 0.0))
    };
    let mut colours: Vec<[f64; 3]> = materials
        .iter()
        .map(|m| {
            let f = &m["pbrMetallicRoughness"]["baseColorFactor"];
            [0, 1, 2].map(|k| f[k].as_f64().unwrap_or(1.0) / style.factor)
        })
        .collect();
    // The emitters' cell: grey, so an emission that ignored its texture would be twice too bright;
    // `emissiveStrength` takes the original factor back to 1 (times the cell).
    let grey = colours.len();
    colours.push([0.5; 3]);
    let grey_decoded = wavrad::scene::srgb_to_linear(f64::from(linear_to_srgb_byte(0.5)) / 255.0);
    let cells = colours.len() as f32;
    let mime = match style.format {
        image::ImageFormat::Jpeg => "image/jpeg",
        _ => "image/png",
    };
    let texture = glb.add_texture(&palette_image(&colours, style.format), mime, None);
    let palette_material = glb.push_array(
        "materials",
        json!({"name": "palette", "pbrMetallicRoughness": {
            "baseColorFactor": [style.factor, style.factor, style.factor, 1.0],
            "baseColorTexture": {"index": texture}, "metallicFactor": 0.0, "roughnessFactor": 1.0}}),
    );
    let meshes = glb.json["meshes"].as_array().unwrap().len();
    for m in 0..meshes {
        let material = glb.json["meshes"][m]["primitives"][0]["material"]
            .as_u64()
            .unwrap() as usize;
        let emissive = is_emissive(&materials[material]);
        let cell = if emissive { grey } else { material };
        let centre = [(cell as f32 + 0.5) / cells, 0.5];
        glb.set_uvs(m, |_| centre);
        if !emissive {
            glb.json["meshes"][m]["primitives"][0]["material"] = json!(palette_material);
        } else if style.emissive_texture {
            let m = &mut glb.json["materials"][material];
            m["emissiveTexture"] = json!({"index": texture});
            m["extensions"] = json!({"KHR_materials_emissive_strength":
                {"emissiveStrength": 1.0 / grey_decoded}});
        }
    }
    glb.glb_bytes()
}

/// Solves a scene at default settings (M2, extended) and returns its probe values' radiance at
/// the reference's points and its nrms against the reference.
fn solve_against(scene: &Scene, set: &ReferenceSet) -> (Vec<[f64; 3]>, f64) {
    let (prepared, solution) = bake(
        scene,
        DomainMode::Extended,
        SolverParams::default(),
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .expect("bakes");
    let values = evaluate_probes(&solution, &set.probes(), prepared.diagonal);
    let nrms = set
        .error(&values)
        .expect("every probe finds a surface")
        .nrms;
    (
        values.iter().map(|v| v.l.unwrap_or([0.0; 3])).collect(),
        nrms,
    )
}

/// nrms of `a` against `b` (RMS difference over b's mean, averaged over channels).
fn nrms_between(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let mut out = 0.0;
    for ch in 0..3 {
        let mean = b.iter().map(|v| v[ch]).sum::<f64>() / b.len() as f64;
        let ms = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x[ch] - y[ch]).powi(2))
            .sum::<f64>()
            / b.len() as f64;
        out += ms.sqrt() / mean / 3.0;
    }
    out
}

#[test]
fn textured_twins_of_the_kenney_building_match_the_untextured_scene() {
    let set_dir = root().join("tests/data/reference/kenney_building_small_c_lit");
    let set = ReferenceSet::load(&set_dir).expect("reference reads");
    let original = std::fs::read(set.scene_in(root())).expect("the Kenney scene is in the repo");
    let plain = load_scene(&original, &ExternalFiles::Refuse, 1_000_000).unwrap();
    assert!(plain.textures.is_empty());
    let (plain_values, plain_nrms) = solve_against(&plain, &set);
    println!("untextured: nrms {:.2} %", 100.0 * plain_nrms);
    let styles = [
        (
            "PNG, factor 1, sky from an emissiveTexture",
            TwinStyle {
                format: image::ImageFormat::Png,
                factor: 1.0,
                emissive_texture: true,
            },
            0.015,
        ),
        (
            "PNG, factor 0.7",
            TwinStyle {
                format: image::ImageFormat::Png,
                factor: 0.7,
                emissive_texture: false,
            },
            0.015,
        ),
        // JPEG moves each cell's colour by its quantisation (up to 3 % of a channel here), and a
        // factor below 1 stores colour / factor in 8 bits (rounded, and clamped at 1): such twins
        // are held to the untextured scene with the colours their texture decodes to.
        (
            "JPEG, factor 1",
            TwinStyle {
                format: image::ImageFormat::Jpeg,
                factor: 1.0,
                emissive_texture: true,
            },
            0.015,
        ),
    ];
    for (name, style, agreement) in styles {
        let (plain_values, plain_nrms) =
            if style.format == image::ImageFormat::Jpeg || style.factor != 1.0 {
                let decoded = with_decoded_colours(&original, style);
                let scene = load_scene(&decoded, &ExternalFiles::Refuse, 1_000_000).unwrap();
                let (values, nrms) = solve_against(&scene, &set);
                println!(
                    "untextured, the twin's decoded colours: nrms {:.2} %",
                    100.0 * nrms
                );
                (values, nrms)
            } else {
                (plain_values.clone(), plain_nrms)
            };
        let twin = load_scene(
            &textured_twin(&original, style),
            &ExternalFiles::Refuse,
            1_000_000,
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(twin.textures.len(), 1, "{name}");
        assert!(twin
            .materials
            .iter()
            .any(|m| m.base_color_texture.is_some()));
        assert_eq!(
            twin.materials.iter().any(|m| m.emissive_texture.is_some()),
            style.emissive_texture
        );
        let (values, nrms) = solve_against(&twin, &set);
        let apart = nrms_between(&values, &plain_values);
        println!(
            "{name}: nrms {:.2} % (untextured {:.2} %), probes {:.2} % apart",
            100.0 * nrms,
            100.0 * plain_nrms,
            100.0 * apart
        );
        assert!(
            (nrms - plain_nrms).abs() <= 0.003,
            "{name}: nrms {nrms} against the untextured {plain_nrms}"
        );
        assert!(apart <= agreement, "{name}: probes {apart} apart");
    }
}

/// The original scene with each non-emissive material's colour replaced by what the twin's
/// palette texture decodes to at its cell's centre (times the factor): the twin's colours, untextured.
fn with_decoded_colours(original: &[u8], style: TwinStyle) -> Vec<u8> {
    let twin = load_scene(
        &textured_twin(original, style),
        &ExternalFiles::Refuse,
        1_000_000,
    )
    .unwrap();
    let texture = &twin.textures[0];
    let mut glb = Glb::parse(original);
    let materials = glb.json["materials"].as_array().unwrap().len();
    let cells = (materials + 1) as f64;
    for m in 0..materials {
        let c = texture.sample(glam::DVec2::new((m as f64 + 0.5) / cells, 0.5));
        let emissive = glb.json["materials"][m]["emissiveFactor"]
            .as_array()
            .is_some_and(|e| e.iter().any(|x| x.as_f64().unwrap_or(0.0) > 0.0));
        if !emissive {
            glb.json["materials"][m]["pbrMetallicRoughness"]["baseColorFactor"] = json!([
                c[0] * style.factor,
                c[1] * style.factor,
                c[2] * style.factor,
                1.0
            ]);
        }
    }
    glb.glb_bytes()
}

/// A 16-bit greyscale PNG of `n` texels in a row whose linear values run from `lo` at the first
/// texel's centre to `hi` at the last one's, as sRGB-encoded values.
fn ramp_png(n: u32, lo: f64, hi: f64) -> (Vec<u8>, Vec<f64>) {
    let mut linear = Vec::new();
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(n, 1, |x, _| {
        let l = lo + (hi - lo) * x as f64 / (n - 1) as f64;
        let s = if l <= 0.0031308 {
            12.92 * l
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        };
        let v = (s * 65535.0).round() as u16;
        linear.push(wavrad::scene::srgb_to_linear(f64::from(v) / 65535.0));
        image::Luma([v])
    });
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    (bytes, linear)
}

/// The ramp as the texture sampler reads it (bilinear, clamped): reflectance at `u` in [0, 1].
fn ramp_at(linear: &[f64], u: f64) -> f64 {
    let n = linear.len();
    let x = (u * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let i = (x.floor() as usize).min(n - 2);
    let f = x - i as f64;
    linear[i] * (1.0 - f) + linear[i + 1] * f
}

/// The ramp's reflectance at `(x, y)` of its face, as the texture reads it: `u = x` (clamped), or
/// with `KHR_texture_transform` scale 2 on `u` and a mirrored-repeat sampler, `u = 2x` mirrored
/// back at 1 (up the ramp, then down again).
fn ramp_reflectance(linear: &[f64], x: f64, mirrored: bool) -> f64 {
    if mirrored {
        let u = 2.0 * x;
        ramp_at(linear, if u > 1.0 { 2.0 - u } else { u })
    } else {
        ramp_at(linear, x)
    }
}

/// The ramp face: the unit square, or (`holed`) the unit square less `[0.4, 0.6]^2`, an extended face.
fn on_ramp(x: f64, y: f64, holed: bool) -> bool {
    !(holed && (0.4..0.6).contains(&x) && (0.4..0.6).contains(&y))
}

/// A face with a texture ramp (reflectance 0.2 -> 0.8 along x) under a directional light straight
/// down (irradiance E everywhere); a black wall at x = 1.2 facing -x (edge-on to the light)
/// receives only the ramp's reflection. Checks the ramp's reflected power against its mean
/// reflectance and the wall's irradiance against a brute-force integral, at every order.
fn ramp_case(holed: bool, mirrored: bool) {
    let e = 2.0;
    let mut b = SceneBuilder::new();
    let ramp = b.material([1.0; 3], [0.0; 3], false);
    let wall = b.material([0.0; 3], [0.0; 3], false);
    let quads: Vec<(DVec3, DVec3, DVec3)> = if holed {
        let (x, y) = (DVec3::X, DVec3::Y);
        vec![
            (DVec3::ZERO, x, y * 0.4),
            (y * 0.6, x, y * 0.4),
            (y * 0.4, x * 0.4, y * 0.2),
            (y * 0.4 + x * 0.6, x * 0.4, y * 0.2),
        ]
    } else {
        vec![(DVec3::ZERO, DVec3::X, DVec3::Y)]
    };
    for &(o, u, v) in &quads {
        b.quad(ramp, o, u, v, 1);
    }
    b.quad(wall, DVec3::new(1.2, 0.0, 0.0), DVec3::Z, DVec3::Y, 1);
    b.light(PunctualLight {
        name: "sun".into(),
        kind: LightKind::Directional {
            direction: DVec3::NEG_Z,
        },
        intensity: [e; 3],
    });
    let mut glb = Glb::parse(&b.to_glb());
    let (png, linear) = ramp_png(64, 0.2, 0.8);
    let (wrap_s, info) = if mirrored {
        (
            33648,
            json!({"extensions": {"KHR_texture_transform": {"scale": [2.0, 1.0]}}}),
        )
    } else {
        (33071, json!({}))
    };
    let sampler = json!({"wrapS": wrap_s, "wrapT": 33071});
    let texture = glb.add_texture(&png, "image/png", Some(sampler));
    let mut info = info;
    info["index"] = json!(texture);
    glb.json["materials"][ramp as usize]["pbrMetallicRoughness"]["baseColorTexture"] = info;
    glb.json["extensionsUsed"]
        .as_array_mut()
        .unwrap()
        .push(json!("KHR_texture_transform"));
    for m in 0..quads.len() {
        glb.set_uvs(m, |p| [p[0], 1.0 - p[1]]);
    }
    let scene = load_scene(&glb.glb_bytes(), &ExternalFiles::Refuse, 1000).unwrap();

    // The ramp's true mean and the wall's mean irradiance, by brute force (midpoint rules).
    let n = 1000;
    let (mut rho_sum, mut count) = (0.0, 0);
    for i in 0..n {
        for j in 0..n {
            let (x, y) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            if on_ramp(x, y, holed) {
                rho_sum += ramp_reflectance(&linear, x, mirrored);
                count += 1;
            }
        }
    }
    let mean_rho = rho_sum / count as f64;
    let (nr, nw) = (100, 24);
    let mut wall_h = 0.0;
    for wi in 0..nw {
        for wj in 0..nw {
            let p = DVec3::new(
                1.2,
                (wj as f64 + 0.5) / nw as f64,
                (wi as f64 + 0.5) / nw as f64,
            );
            let mut h = 0.0;
            for i in 0..nr {
                let x = (i as f64 + 0.5) / nr as f64;
                let b_x = ramp_reflectance(&linear, x, mirrored) * e;
                for j in 0..nr {
                    let y = (j as f64 + 0.5) / nr as f64;
                    if !on_ramp(x, y, holed) {
                        continue;
                    }
                    let d = p - DVec3::new(x, y, 0.0);
                    let r2 = d.length_squared();
                    let cos_q = d.z / r2.sqrt();
                    let cos_p = d.x / r2.sqrt();
                    h += b_x * cos_q * cos_p / (std::f64::consts::PI * r2);
                }
            }
            wall_h += h / (nr * nr) as f64;
        }
    }
    wall_h /= (nw * nw) as f64;

    for order in 1..=3 {
        let params = SolverParams {
            order,
            quantity: Quantity::Irradiance,
            ..SolverParams::default()
        };
        let (prepared, solution) = bake(
            &scene,
            DomainMode::Extended,
            params,
            &AtomicBool::new(false),
            &mut |_| {},
        )
        .unwrap();
        let face_of = |normal: DVec3| {
            prepared
                .faces
                .faces
                .iter()
                .position(|f| f.normal.dot(normal) > 0.99)
                .unwrap()
        };
        let root_of = |face: usize| {
            solution
                .roots
                .iter()
                .position(|r| r.face.0 as usize == face)
                .unwrap()
        };
        let ramp_root = root_of(face_of(DVec3::Z));
        let wall_root = root_of(face_of(DVec3::NEG_X));
        assert!(solution.roots[ramp_root].reflectance.is_some());
        assert_eq!(solution.roots[ramp_root].mask.is_some(), holed);
        let reflected = solution.mean_radiosity(ramp_root)[0];
        let expected = mean_rho * e;
        let received = std::f64::consts::PI * solution.mean_value(wall_root)[0];
        println!(
            "{} M{order}: ramp reflects {reflected:.5} W/m^2 (mean rho x E = {expected:.5}, {:+.3} %), \
             wall receives {received:.6} (brute force {wall_h:.6}, {:+.3} %)",
            if holed { "holed, mirrored x2" } else { "square, clamped" },
            100.0 * (reflected / expected - 1.0),
            100.0 * (received / wall_h - 1.0)
        );
        assert!(
            (reflected / expected - 1.0).abs() < 0.005,
            "M{order}: {reflected} vs {expected}"
        );
        assert!(
            (received / wall_h - 1.0).abs() < 0.01,
            "M{order}: {received} vs {wall_h}"
        );
    }
}

#[test]
fn a_texture_ramp_reflects_its_mean_and_lights_a_wall_as_a_brute_force_integral() {
    ramp_case(false, false);
}

/// The same on an extended face (a square with a hole), through `KHR_texture_transform` and a
/// mirrored-repeat sampler.
#[test]
fn a_mirrored_transformed_ramp_on_a_holed_face_does_the_same() {
    ramp_case(true, true);
}

#[test]
fn a_texture_that_cannot_be_read_is_refused_with_its_name() {
    let mut b = SceneBuilder::new();
    let m = b.material([1.0; 3], [0.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    let base = b.to_glb();

    // Bytes that are no image.
    let mut glb = Glb::parse(&base);
    let t = glb.add_texture(b"definitely not a PNG", "image/png", None);
    glb.json["images"][0]["name"] = json!("wall_albedo");
    glb.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": t});
    glb.set_uvs(0, |p| [p[0], p[1]]);
    let err = load_scene(&glb.glb_bytes(), &ExternalFiles::Refuse, 1000).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, SceneError::Invalid(_)), "{message}");
    assert!(message.contains("image 0 ('wall_albedo')"), "{message}");

    // A good image whose TEXCOORD_1 the primitive lacks.
    let mut glb = Glb::parse(&base);
    let png = palette_image(&[[0.5; 3]], image::ImageFormat::Png);
    let t = glb.add_texture(&png, "image/png", None);
    glb.json["materials"][0]["emissiveTexture"] = json!({"index": t, "texCoord": 1});
    glb.json["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    glb.set_uvs(0, |p| [p[0], p[1]]);
    let message = load_scene(&glb.glb_bytes(), &ExternalFiles::Refuse, 1000)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("mesh 0 primitive 0") && message.contains("TEXCOORD_1"),
        "{message}"
    );

    // An external image over HTTP (never resolved against the server's disk).
    let mut glb = Glb::parse(&base);
    glb.push_array("images", json!({"uri": "albedo.png"}));
    let t = glb.push_array("textures", json!({"source": 0}));
    glb.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": t});
    glb.set_uvs(0, |p| [p[0], p[1]]);
    let message = load_scene(&glb.glb_bytes(), &ExternalFiles::Refuse, 1000)
        .unwrap_err()
        .to_string();
    assert!(message.contains("albedo.png"), "{message}");
}

#[test]
fn vertex_colours_and_alpha_are_named_in_a_warning() {
    let mut b = SceneBuilder::new();
    let m = b.material([1.0; 3], [0.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    let mut glb = Glb::parse(&b.to_glb());
    let colours: Vec<u8> = [0.5f32; 12].iter().flat_map(|c| c.to_le_bytes()).collect();
    let view = glb.push_view(&colours);
    let accessor = glb.push_array(
        "accessors",
        json!({"bufferView": view, "componentType": 5126, "count": 4, "type": "VEC3"}),
    );
    glb.json["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(accessor);
    glb.json["materials"][0]["alphaMode"] = json!("BLEND");
    let scene = load_scene(&glb.glb_bytes(), &ExternalFiles::Refuse, 1000).unwrap();
    let warnings = scene.warnings.join("\n");
    assert!(warnings.contains("COLOR_0"), "{warnings}");
    assert!(warnings.contains("alphaMode"), "{warnings}");
}

#[test]
fn a_file_that_is_not_gltf_2_is_refused() {
    let mut b = SceneBuilder::new();
    let m = b.material([1.0; 3], [0.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    for (field, value) in [("version", "1.0"), ("minVersion", "3.0")] {
        let mut glb = Glb::parse(&b.to_glb());
        glb.json["asset"][field] = json!(value);
        let err = load_scene(&glb.glb_bytes(), &ExternalFiles::Refuse, 1000).unwrap_err();
        assert!(matches!(err, SceneError::Unreadable(_)));
        assert!(err.to_string().contains(value), "{err}");
    }
}

#[test]
fn the_cli_reads_images_next_to_a_gltf_and_refuses_gltf_1() {
    let dir = std::env::temp_dir().join(format!("wavrad-textures-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (gltf, bin, png) = glowing_quad_gltf("2.0");
    std::fs::write(dir.join("scene.gltf"), gltf).unwrap();
    std::fs::write(dir.join("scene.bin"), &bin).unwrap();
    std::fs::write(dir.join("glow.png"), png).unwrap();
    let out_dir = dir.join("out");
    let scene = dir.join("scene.gltf");
    let out = wavrad(&[
        "solve",
        scene.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--order",
        "1",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let result: Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("result.json")).unwrap()).unwrap();
    let mean = result["faces"][0]["mean_radiance"][0].as_f64().unwrap();
    assert!(
        (mean - glow()).abs() < 1e-6,
        "emission {mean}, texture {}",
        glow()
    );

    // Without its image: exit 2 naming it.
    std::fs::remove_file(dir.join("glow.png")).unwrap();
    let out = wavrad(&["faces", scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("glow.png"));

    // asset.version 1.0: exit 2 from both commands, with the reason.
    let (gltf, _, png) = glowing_quad_gltf("1.0");
    std::fs::write(dir.join("glow.png"), png).unwrap();
    std::fs::write(&scene, gltf).unwrap();
    for args in [
        vec!["faces", scene.to_str().unwrap()],
        vec![
            "solve",
            scene.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ],
    ] {
        let out = wavrad(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("asset.version") && stderr.contains("1.0"),
            "{stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
