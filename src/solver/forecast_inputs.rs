//! What the indirect forecast (`indirect_forecast.rs`) is fed from the solve: at the start of
//! the first direct shot, what each receiver is foreseen to get and reflect, its share of the
//! shooter as a few cosine-weighted rays see it (`seen_fraction`); and the forecast itself from
//! unshot power per root, the roots exchanging light as a shot's plan foresees it
//! (`unoccluded.rs`).
//!
//! Invariant: nothing here changes the solve: it reads the scene and traces rays only to
//! estimate, and its result goes to the ETA alone.

use super::hierarchy::Hierarchy;
use super::indirect_forecast::{forecast, ForecastInput, IndirectForecast};
use super::mean_rgb_sum;
use super::refine::ShotContext;
use super::unoccluded::{faces_each_other, unoccluded_received};
use crate::domain::{plane_coordinates, ElementRoot, Shape};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// The indirect phase foreseen at the start of the first direct shot, from what that shot (of
/// root `shooter`) is expected to leave unshot, until the direct phase ends and leaves the real
/// figure (`shooting.rs`). `received` is what each root would get from the shot with no
/// occluder (negative when it is not visited), `unshot` the roots' unshot power before it. Each
/// receiver keeps its share as the few rays of [`seen_fraction`] see it (the plan has no
/// occluder: under a sky it would count every wall between buildings); emitters' unshot power
/// is their emission until their own direct shots take it, so it is left out; the target is
/// `target_unshot` of the power the shot is foreseen to deliver.
pub(super) fn foresee_after_direct_shot(
    ctx: &ShotContext,
    (hierarchies, unshot): (&[Hierarchy], &[f64]),
    (shooter, received): (usize, &[f64]),
    target_unshot: f64,
    facing_eps: f64,
) -> IndirectForecast {
    let roots = ctx.roots;
    let seen: Vec<f64> = (0..roots.len())
        .into_par_iter()
        .map(|ri| {
            if received[ri] > 0.0 {
                seen_fraction(ctx, shooter, ri)
            } else {
                0.0
            }
        })
        .collect();
    let emits = |ri: usize| mean_rgb_sum(roots[ri].exitance) > 0.0;
    let reflected = |ri: usize| received[ri].max(0.0) * mean_rgb_sum(roots[ri].rho) / 3.0;
    let after: Vec<f64> = (0..roots.len())
        .map(|ri| if emits(ri) { 0.0 } else { unshot[ri] } + reflected(ri) * seen[ri])
        .collect();
    let base: f64 = (0..roots.len())
        .map(|ri| received[ri].max(0.0) * seen[ri])
        .sum();
    foresee_indirect(ctx, hierarchies, &after, target_unshot * base, facing_eps)
}

/// Directions of [`seen_fraction`]'s rays: a 2 x 4 stratified grid of the unit square, mapped
/// to the hemisphere with a density in the cosine (the form factor's weight at the receiver).
const SEEN_DIRECTIONS: [(f64, f64); 8] = [
    (0.25, 0.125),
    (0.25, 0.375),
    (0.25, 0.625),
    (0.25, 0.875),
    (0.75, 0.0),
    (0.75, 0.25),
    (0.75, 0.5),
    (0.75, 0.75),
];

/// The share of root `shooter` that root `ri` sees, from its link point: of the directions of
/// [`SEEN_DIRECTIONS`] (the receiver's hemisphere, cosine-weighted) that meet the shooter's
/// domain, those whose ray reaches it; when none meets it (a source small in the receiver's
/// view), the rays to the shooter's link point and to the points halfway from there to its
/// corners. A wall under an eave sees a sky panel mostly past the eave, low towards the
/// horizon, where rays towards the panel's middle are blocked (`tests::seen_directions_*`,
/// `tests::a_ray_meets_a_root_where_its_twin_does`).
fn seen_fraction(ctx: &ShotContext, shooter: usize, ri: usize) -> f64 {
    let (sroot, root) = (&ctx.roots[shooter], &ctx.roots[ri]);
    let (c, p) = (ctx.link_points[shooter], ctx.link_points[ri]);
    let ignore = [sroot.face.0, root.face.0];
    let (mut seen, mut all) = (0u32, 0u32);
    for d in seen_directions(root.normal) {
        if let Some(q) = ray_meets_root(p, d, sroot) {
            all += 1;
            if ctx.visibility.visible(p, q, ignore) {
                seen += 1;
            }
        }
    }
    if all > 0 {
        return f64::from(seen) / f64::from(all);
    }
    let corners = sroot.corners();
    let targets = std::iter::once(c).chain(corners.iter().map(|&k| c + 0.5 * (k - c)));
    for q in targets {
        all += 1;
        if ctx.visibility.visible(p, q, ignore) {
            seen += 1;
        }
    }
    f64::from(seen) / f64::from(all)
}

/// [`SEEN_DIRECTIONS`] about the normal `n`, as unit vectors.
fn seen_directions(n: DVec3) -> impl Iterator<Item = DVec3> {
    let t1 = n.any_orthonormal_vector();
    let t2 = n.cross(t1);
    SEEN_DIRECTIONS.iter().map(move |&(a, b)| {
        let (r, phi) = (a.sqrt(), std::f64::consts::TAU * b);
        t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + n * (1.0 - a).sqrt()
    })
}

/// Where the ray from `p` along `d` meets `root`'s domain from its front side, if it does.
fn ray_meets_root(p: DVec3, d: DVec3, root: &ElementRoot) -> Option<DVec3> {
    let f = &root.frame;
    let across = root.normal.dot(d);
    if across >= 0.0 {
        return None;
    }
    let t = root.normal.dot(f.origin - p) / across;
    if t <= 0.0 {
        return None;
    }
    let hit = p + d * t;
    let DVec2 { x: s, y: w } = plane_coordinates(f, hit);
    let inside = match root.shape {
        Shape::Triangle => s >= 0.0 && w >= 0.0 && s + w <= 1.0,
        Shape::Parallelogram => (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&w),
    };
    inside.then_some(hit)
}

/// The indirect phase foreseen (`indirect_forecast.rs`) from `unshot` W per root, down to
/// `target` W: reflected light lands in proportion to face area times reflectance, and roots
/// exchange light as a shot's plan foresees it (`unoccluded_received`, `faces_each_other`).
pub(super) fn foresee_indirect(
    ctx: &ShotContext,
    hierarchies: &[Hierarchy],
    unshot: &[f64],
    target: f64,
    facing_eps: f64,
) -> IndirectForecast {
    let roots = ctx.roots;
    let receives = |r: usize| !hierarchies[r].nodes.is_empty();
    let share: Vec<f64> = (0..roots.len())
        .map(|r| {
            if receives(r) {
                roots[r].face_area_m2 * mean_rgb_sum(roots[r].rho)
            } else {
                0.0
            }
        })
        .collect();
    let input = ForecastInput {
        unshot,
        share: &share,
        target,
        threshold: ctx.threshold,
    };
    let faces = |s: usize, r: usize| {
        let (ss, sr) = (&ctx.spheres[s], &ctx.spheres[r]);
        receives(r) && faces_each_other(&roots[s], ss, &roots[r], sr, facing_eps)
    };
    forecast(
        &input,
        &|s, r| {
            faces(s, r).then(|| {
                unoccluded_received(ctx, s, 1.0, r, false) * mean_rgb_sum(roots[r].rho) / 3.0
            })
        },
        &faces,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::element::tests::parallelogram_root;

    /// The directions of the seen fraction: unit, in the hemisphere, their mean cosine that of a
    /// cosine-weighted hemisphere (2/3, within the grid's error) and no tangential bias.
    #[test]
    fn seen_directions_are_cosine_weighted() {
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        let mut sum = DVec3::ZERO;
        for d in seen_directions(n) {
            assert!((d.length() - 1.0).abs() < 1e-12 && d.dot(n) > 0.0);
            sum += d;
        }
        let mean = sum / SEEN_DIRECTIONS.len() as f64;
        assert!((mean.dot(n) - 2.0 / 3.0).abs() < 0.02, "{}", mean.dot(n));
        assert!((mean - n * mean.dot(n)).length() < 1e-12);
    }

    /// `ray_meets_root` against a twin: the hit on the plane from the corners' normal, inside
    /// when on the inner side of every edge; random roots of both shapes, rays from random
    /// points on either side aimed around them (only those reaching the front count).
    #[test]
    fn a_ray_meets_a_root_where_its_twin_does() {
        let mut rnd = crate::shuffle::uniform_sequence(91);
        let mut vector = |scale: f64| DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * scale;
        let (mut hits, mut misses) = (0, 0);
        for i in 0..20_000 {
            let mut root = parallelogram_root(vector(2.0), vector(2.0), vector(2.0));
            if i % 2 == 1 {
                root.shape = Shape::Triangle;
            }
            // Aimed at the root's plane around it: about half reach the front inside.
            let p = vector(6.0);
            let w = vector(2.0);
            let st = glam::DVec2::new(w.x + 0.5, w.y + 0.5);
            let d = (root.frame.point(st) - p).normalize();
            let corners = root.corners();
            let k = corners.len();
            let normal = (corners[1] - corners[0])
                .cross(corners[k - 1] - corners[0])
                .normalize();
            let twin = {
                let t = normal.dot(corners[0] - p) / normal.dot(d);
                let x = p + d * t;
                let inner = (0..k).all(|e| {
                    let (a, b) = (corners[e], corners[(e + 1) % k]);
                    (b - a).cross(x - a).dot(normal) >= 0.0
                });
                (normal.dot(d) < 0.0 && t > 0.0 && inner).then_some(x)
            };
            match (ray_meets_root(p, d, &root), twin) {
                (Some(a), Some(b)) => {
                    assert!(a.distance(b) < 1e-9, "{a} {b}");
                    hits += 1;
                }
                (None, None) => misses += 1,
                (a, b) => panic!("{i}: {a:?} against {b:?}"),
            }
        }
        assert!(hits > 1000 && misses > 1000, "{hits} {misses}");
    }
}
