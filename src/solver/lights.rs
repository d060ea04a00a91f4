//! Punctual lights (`KHR_lights_punctual`): point, spot and directional lights shine directly on
//! the receivers as the solve's first shots (docs/design.md section 5.1).
//!
//! Owns the glTF light formulas: [`unoccluded_irradiance`] (the light's irradiance at a point
//! before occlusion), [`shadow_target`] and the power estimate that scales the error threshold.
//! A light shoots as a `source::LightSource`, through the same transfer and oracle as elements.
//! The light's delivered power, the integral of that irradiance over the receivers, counts in
//! the emitted power of `unshot_ratio` (docs/contract.md). Units: intensity in W/sr (candela) for point
//! and spot lights, irradiance in W/m^2 (lux) for directional lights.

use super::mean_rgb_sum;
use crate::domain::ElementRoot;
use crate::scene::{LightKind, PunctualLight, Rgb};
use glam::DVec3;

/// The direct irradiance of `light` at `x` on a surface of unit normal `n`, ignoring occlusion,
/// and the point a shadow ray from `x` must reach (the light, or far along a directional light).
/// `far` is a distance beyond the scene.
pub fn unoccluded_irradiance(light: &PunctualLight, x: DVec3, n: DVec3, far: f64) -> (Rgb, DVec3) {
    let scale = |k: f64| light.intensity.map(|c| c * k);
    match light.kind {
        LightKind::Point { position } => {
            let d = position - x;
            let r2 = d.length_squared();
            if r2 <= 0.0 {
                return ([0.0; 3], position);
            }
            let cos = n.dot(d) / r2.sqrt();
            (scale((cos / r2).max(0.0)), position)
        }
        LightKind::Spot {
            position,
            direction,
            inner_cone_angle,
            outer_cone_angle,
        } => {
            let d = position - x;
            let r2 = d.length_squared();
            if r2 <= 0.0 {
                return ([0.0; 3], position);
            }
            let r = r2.sqrt();
            let cos = n.dot(d) / r;
            // The glTF extension's smooth cone falloff (its recommended implementation).
            let (cos_outer, cos_inner) = (outer_cone_angle.cos(), inner_cone_angle.cos());
            let angle_scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
            let cd = direction.dot(-d / r);
            let t = ((cd - cos_outer) * angle_scale).clamp(0.0, 1.0);
            (scale((cos / r2).max(0.0) * t * t), position)
        }
        LightKind::Directional { direction } => {
            let cos = -n.dot(direction);
            (scale(cos.max(0.0)), shadow_target(light, x, far))
        }
    }
}

/// The point a shadow ray from `x` must reach: the light's position, or `far` back along a
/// directional light.
pub fn shadow_target(light: &PunctualLight, x: DVec3, far: f64) -> DVec3 {
    match light.kind {
        LightKind::Point { position } | LightKind::Spot { position, .. } => position,
        LightKind::Directional { direction } => x - direction * far,
    }
}

/// The power a light delivers onto `roots` if nothing occluded it, from each root's centroid: the
/// scale of the solve's error threshold before the light has shot.
pub fn unoccluded_power_estimate(light: &PunctualLight, roots: &[ElementRoot], far: f64) -> f64 {
    roots
        .iter()
        .map(|r| {
            let c = r.corners();
            let centroid = c.iter().copied().sum::<DVec3>() / c.len() as f64;
            mean_rgb_sum(unoccluded_irradiance(light, centroid, r.normal, far).0) * r.face_area_m2
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(kind: LightKind) -> PunctualLight {
        PunctualLight {
            name: "l".into(),
            kind,
            intensity: [100.0, 50.0, 10.0],
        }
    }

    #[test]
    fn point_light_follows_the_inverse_square_and_cosine_laws() {
        let l = light(LightKind::Point {
            position: DVec3::new(0.0, 2.0, 0.0),
        });
        let (e, target) = unoccluded_irradiance(&l, DVec3::ZERO, DVec3::Y, 100.0);
        assert_eq!(target, DVec3::new(0.0, 2.0, 0.0));
        assert!((e[0] - 25.0).abs() < 1e-12 && (e[2] - 2.5).abs() < 1e-12);
        // 45 degrees off the normal at distance 2 sqrt 2: I cos / r^2 = 100 (1/sqrt 2) / 8.
        let (e, _) = unoccluded_irradiance(&l, DVec3::new(2.0, 0.0, 0.0), DVec3::Y, 100.0);
        assert!((e[0] - 100.0 / 8.0 / 2f64.sqrt()).abs() < 1e-12);
        // Behind the surface: nothing.
        let (e, _) = unoccluded_irradiance(&l, DVec3::ZERO, DVec3::NEG_Y, 100.0);
        assert_eq!(e, [0.0; 3]);
    }

    #[test]
    fn spot_light_is_full_inside_its_inner_cone_and_dark_outside_its_outer_cone() {
        let l = light(LightKind::Spot {
            position: DVec3::new(0.0, 1.0, 0.0),
            direction: DVec3::NEG_Y,
            inner_cone_angle: 0.3,
            outer_cone_angle: 0.5,
        });
        let at = |x: f64| unoccluded_irradiance(&l, DVec3::new(x, 0.0, 0.0), DVec3::Y, 10.0).0[0];
        assert!((at(0.0) - 100.0).abs() < 1e-12);
        // Inside the inner cone (tan 0.3 = 0.309): full intensity, cos^3 law.
        let c = (1.0f64 / (1.0 + 0.25f64 * 0.25)).sqrt();
        assert!((at(0.25) - 100.0 * c * c * c).abs() < 1e-9);
        // Outside the outer cone (tan 0.5 = 0.546): dark.
        assert_eq!(at(0.6), 0.0);
        // Between: strictly between.
        let mid = at(0.42);
        let c = (1.0f64 / (1.0 + 0.42f64 * 0.42)).sqrt();
        assert!(mid > 0.0 && mid < 100.0 * c * c * c);
    }

    #[test]
    fn directional_light_is_its_irradiance_times_the_cosine() {
        let d = DVec3::new(1.0, -1.0, 0.0).normalize();
        let l = light(LightKind::Directional { direction: d });
        let (e, target) = unoccluded_irradiance(&l, DVec3::ZERO, DVec3::Y, 10.0);
        assert!((e[0] - 100.0 / 2f64.sqrt()).abs() < 1e-12);
        assert!((target - (-d * 10.0)).length() < 1e-12);
    }
}
