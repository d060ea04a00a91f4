//! An element's rule carried onto the part of it in front of a receiver point's tangent plane
//! ([`FrontRule`], by `FrontMap`): when the plane cuts a native or wholly covered element behind
//! some of its emitting rule points, the points in front sample the front part (`front_rule`),
//! and what the element delivers is taken over them (`front_irradiance`).
//!
//! Invariant: the flags and the sampling error are [`ElementSource::with_verdicts`]' own, with
//! the front rule's points in place of the element's; the map is a quadrature of the front part
//! (`front_map.rs`).

use super::{trace_packet, verdicts, ElementSource, POINTS};
use crate::domain::ElementStatus;
use crate::scene::Rgb;
use crate::solver::basis::MAX_FUNCTIONS;
use crate::solver::front_map::FrontMap;
use crate::solver::kernel;
use crate::solver::source::{PointIrradiance, Rays};
use glam::DVec3;

/// An element's rule carried onto its part in front of a receiver point's plane
/// ([`ElementSource::front_rule`]): the points, their weights (the rule's times the map's
/// Jacobian, summing to the front part's share of the element) and the radiosity there.
pub(super) struct FrontRule {
    points: [DVec3; POINTS],
    weights: [f64; POINTS],
    radiosity: [Rgb; POINTS],
    len: usize,
}

impl ElementSource<'_> {
    /// The rule carried onto the part of the element in front of receiver point `x`'s plane
    /// (normal `n`), when some emitting rule point lies behind it: the rule's points there
    /// exchange no light, and those in front sample the front part unevenly (under an eave, a
    /// sky element cut by the wall's plane kept one column of points far from the wall, all of
    /// them seen past the eave, while its front part nearest the wall, which the eave hides,
    /// had no point). Native elements and wholly covered ones of an extended root (a partly
    /// covered element's points are tied to the face inside it). `None` when no emitting point
    /// lies behind. The map, and the test that pins it as a quadrature of the front part:
    /// `front_map.rs`.
    pub(super) fn front_rule(&self, x: DVec3, n: DVec3) -> Option<FrontRule> {
        if self.partial
            || self
                .src
                .cover
                .is_some_and(|c| c.status != ElementStatus::Full)
        {
            return None;
        }
        let behind =
            (0..self.rule.len()).any(|l| self.alpha[l] > 0.0 && (self.ys[l] - x).dot(n) <= 0.0);
        if !behind {
            return None;
        }
        let h0 = (self.patch.origin - x).dot(n);
        let map = FrontMap::new(
            self.root.shape,
            h0,
            self.patch.u.dot(n),
            self.patch.v.dot(n),
        )?;
        let basis = self.shot.bases.of(self.root.shape);
        let ns = basis.len();
        let mut rule = FrontRule {
            points: [DVec3::ZERO; POINTS],
            weights: [0.0; POINTS],
            radiosity: [[0.0; 3]; POINTS],
            len: 0,
        };
        let mut phi = [0.0; MAX_FUNCTIONS];
        for q in self.rule {
            let (st, jacobian) = map.apply(q.st);
            let i = rule.len;
            rule.points[i] = self.patch.point(st);
            rule.weights[i] = q.weight * jacobian;
            basis.eval(st, &mut phi);
            for bfn in 0..ns {
                for ch in 0..3 {
                    rule.radiosity[i][ch] += phi[bfn] * self.src.coeffs[bfn][ch];
                }
            }
            rule.len += 1;
        }
        Some(rule)
    }

    /// What the source delivers at `x` (normal `n`, exact form factor `f`) sampled by the
    /// `front` rule, its shadow rays decided as `rays` says (one per point; every point seen; or
    /// one ray, to the front part's centroid, for all of them) unless `known` (an earlier
    /// shot's, [`PointIrradiance::seen`]): the visible points' kernel-weighted radiosity scaled
    /// to `f`, and the flags and the sampling error as [`ElementSource::with_verdicts`] gives
    /// them with the element's own rule. `None` when no front point exchanges light (a sliver
    /// of front part at grazing angles).
    pub(super) fn front_irradiance(
        &self,
        (x, n, f): (DVec3, DVec3, f64),
        ignore: [u32; 2],
        front: &FrontRule,
        (rays, known): (Rays, Option<u64>),
    ) -> Option<PointIrradiance> {
        let k = front.len;
        let mut terms = [0.0; POINTS];
        let mut fq = 0.0;
        for i in 0..k {
            terms[i] = kernel::geometric_kernel(x, n, front.points[i], self.root.normal)
                * self.patch.area
                * front.weights[i];
            fq += terms[i];
        }
        if fq <= 0.0 {
            return None;
        }
        let visibility = self.shot.visibility;
        let seen = verdicts(
            (rays, known),
            || trace_packet(visibility, x, &front.points[..k], ignore),
            || {
                let w: f64 = front.weights[..k].iter().sum();
                let centroid = (0..k)
                    .map(|i| front.points[i] * front.weights[i])
                    .sum::<DVec3>()
                    / w;
                trace_packet(visibility, x, &[centroid], ignore)
            },
        );
        let mut out = self.unread_answer(f, seen);
        let unoccluded = out.unoccluded;
        let mut e = [0.0; 3];
        let (mut front_weight, mut front_visible) = (0.0, 0.0);
        for i in 0..k {
            if terms[i] <= 0.0 {
                continue;
            }
            front_weight += front.weights[i];
            if seen >> i & 1 == 1 {
                out.any_visible = true;
                front_visible += front.weights[i];
                for ch in 0..3 {
                    e[ch] += terms[i] * front.radiosity[i][ch];
                }
            } else {
                out.any_blocked = true;
            }
        }
        let v = front_visible / front_weight;
        out.source_side_err = unoccluded * 2.0 * v.min(1.0 - v).max(0.0);
        out.e = e.map(|c| c * f / fq);
        Some(out)
    }
}
