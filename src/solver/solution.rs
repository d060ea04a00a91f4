//! The solved scene's evaluation: [`Solution`] rebuilt from saved parts, its irradiance and the
//! requested quantity at a point, and face means (clamped for output, raw for checks).
//!
//! Invariant: a solution's hierarchies hold their covers and reflectance per node (recomputed by
//! `from_saved`), so face integrals and point values read the same tree the solve built.

use super::basis::{Basis, ChildMap};
use super::cover;
use super::hierarchy::{self, Hierarchy};
use super::rules::{Bases, Rules};
use super::{Progress, Quantity, SolveStats, SolverParams};
use crate::domain::ElementRoot;
use crate::scene::Rgb;
use glam::DVec2;

/// The solved scene: roots, their hierarchies, and what it took.
#[derive(Debug)]
pub struct Solution {
    pub roots: Vec<ElementRoot>,
    pub hierarchies: Vec<Hierarchy>,
    pub params: SolverParams,
    pub stats: SolveStats,
    pub convergence: Vec<Progress>,
    bases: Bases,
}

impl Solution {
    /// The solve's result (`shooting::solve`).
    pub(super) fn new(
        roots: Vec<ElementRoot>,
        hierarchies: Vec<Hierarchy>,
        params: SolverParams,
        stats: SolveStats,
        convergence: Vec<Progress>,
        bases: Bases,
    ) -> Self {
        Solution {
            roots,
            hierarchies,
            params,
            stats,
            convergence,
            bases,
        }
    }

    /// A solution rebuilt from saved parts: the roots (rebuilt by the caller exactly as for the
    /// solve), per root its hierarchy with `nodes`, `h` and `hd` (`u` and `dh` may be empty: they
    /// are zeroed; `covers` are recomputed), and the parameters. Stats and convergence are empty.
    /// Refuses parts that do not fit together (counts, coefficient lengths, non-tree nodes).
    pub fn from_saved(
        roots: Vec<ElementRoot>,
        mut hierarchies: Vec<Hierarchy>,
        params: SolverParams,
    ) -> Result<Solution, String> {
        if !(1..=3).contains(&params.order) {
            return Err(format!("order {} is not 1, 2 or 3", params.order));
        }
        if roots.len() != hierarchies.len() {
            return Err(format!(
                "{} hierarchies for {} roots",
                hierarchies.len(),
                roots.len()
            ));
        }
        let bases = Bases::new(params.order);
        let rules = Rules::new(params.order);
        for (i, (h, r)) in hierarchies.iter_mut().zip(&roots).enumerate() {
            let basis = bases.of(r.shape);
            let coeffs = h.nodes.len() * basis.len();
            if h.len != basis.len() || h.h.len() != coeffs || h.hd.len() != coeffs {
                return Err(format!("root {i}: coefficient arrays do not fit its nodes"));
            }
            hierarchy::check_tree(&h.nodes).map_err(|e| format!("root {i}: {e}"))?;
            // Covers need the elements of an extended root to be boxes of its (s, t) square.
            let boxes =
                |m: &ChildMap| m.e1.y == 0.0 && m.e2.x == 0.0 && m.e1.x > 0.0 && m.e2.y > 0.0;
            if r.mask.is_some() && !h.nodes.iter().all(|n| boxes(&n.map)) {
                return Err(format!(
                    "root {i}: an element of an extended root is not a box"
                ));
            }
            h.u = vec![[0.0; 3]; coeffs];
            h.dh = vec![[0.0; 3]; coeffs];
            h.touched = false;
            h.rebuild_side_tables(r, basis, &rules.cover);
        }
        Ok(Solution {
            roots,
            hierarchies,
            params,
            stats: SolveStats::default(),
            convergence: Vec::new(),
            bases,
        })
    }

    pub fn basis(&self, root: usize) -> &Basis {
        self.bases.of(self.roots[root].shape)
    }

    /// Irradiance H at root point `st` (all light, or indirect only when the job asked for it).
    pub fn irradiance_at(&self, root: usize, st: DVec2) -> Rgb {
        let r = &self.roots[root];
        let h = &self.hierarchies[root];
        let (leaf, local) = h.locate(st, r.shape);
        let basis = self.basis(root);
        let total = basis.value(h.coeffs(&h.h, leaf), local);
        if self.params.indirect_only {
            let direct = basis.value(h.coeffs(&h.hd, leaf), local);
            [0, 1, 2].map(|c| total[c] - direct[c])
        } else {
            total
        }
    }

    /// The requested quantity at root point `st` (radiance `B/pi` or `H/pi`), clamped at 0. On a
    /// textured face, radiance takes the reflectance and emission of the texture at the point.
    pub fn value_at(&self, root: usize, st: DVec2) -> Rgb {
        let h = self.irradiance_at(root, st);
        let r = &self.roots[root];
        let (rho, emitted) = match &r.reflectance {
            Some(map) => {
                let (rho, le) = map.texture.at(r.frame.point(st));
                (rho, le.map(|x| std::f64::consts::PI * x))
            }
            None => (r.rho, r.exitance),
        };
        self.quantity(h, [0, 1, 2].map(|c| rho[c] * h[c]), emitted)
            .map(|v| v.max(0.0))
    }

    /// Radiance `(E + reflected) / pi` or `H / pi`, from irradiance `h`, the radiosity it reflects
    /// and the exitance `e` (left out with `indirect_only`).
    fn quantity(&self, h: Rgb, reflected: Rgb, e: Rgb) -> Rgb {
        let pi = std::f64::consts::PI;
        match self.params.quantity {
            Quantity::Irradiance => h.map(|x| x / pi),
            Quantity::Radiance => {
                let e = if self.params.indirect_only {
                    [0.0; 3]
                } else {
                    e
                };
                [0, 1, 2].map(|c| (e[c] + reflected[c]) / pi)
            }
        }
    }

    /// Mean over the root's face of the radiosity its received irradiance reflects (all light,
    /// or indirect only): `rho` times the mean irradiance, or, where the reflectance varies, each
    /// leaf's reflectance times its irradiance, integrated over the face.
    fn face_mean_reflected(&self, root: usize, indirect: bool, clamp_leaves: bool) -> Rgb {
        let r = &self.roots[root];
        let h = &self.hierarchies[root];
        if h.reflectance.is_empty() {
            let mean_h = self.face_mean_irradiance(root, indirect, clamp_leaves);
            return [0, 1, 2].map(|c| r.rho[c] * mean_h[c]);
        }
        let n = h.len;
        let coeff = |k: usize| -> Rgb {
            let rho = h.reflectance[k / n].mean;
            [0, 1, 2].map(|c| {
                let x = if indirect {
                    h.h[k][c] - h.hd[k][c]
                } else {
                    h.h[k][c]
                };
                rho[c] * x
            })
        };
        let clamp = |x: f64| if clamp_leaves && x < 0.0 { 0.0 } else { x };
        if r.mask.is_none() {
            // Coefficient 0 is a leaf's mean; its share of the root is its map's determinant.
            let mut sum = [0.0; 3];
            for (i, node) in h.nodes.iter().enumerate() {
                if node.is_leaf() {
                    let share = node.map.e1.perp_dot(node.map.e2).abs();
                    let c = coeff(i * n);
                    for ch in 0..3 {
                        sum[ch] += clamp(share * c[ch]);
                    }
                }
            }
            return sum;
        }
        if r.face_area_m2 <= 0.0 {
            return coeff(0);
        }
        cover::face_integral_by(h, r, clamp_leaves, coeff).map(|x| x / r.face_area_m2)
    }

    /// Mean over the root's face of the irradiance received (all light, or indirect only):
    /// coefficient 0 for a native root; for an extended one the integral over its face, each
    /// leaf's part clamped at 0 when `clamp_leaves`.
    fn face_mean_irradiance(&self, root: usize, indirect: bool, clamp_leaves: bool) -> Rgb {
        let r = &self.roots[root];
        let h = &self.hierarchies[root];
        let coeff = |k: usize| -> Rgb {
            if indirect {
                [0, 1, 2].map(|c| h.h[k][c] - h.hd[k][c])
            } else {
                h.h[k]
            }
        };
        if r.mask.is_none() || r.face_area_m2 <= 0.0 {
            return coeff(0);
        }
        cover::face_integral_by(h, r, clamp_leaves, coeff).map(|x| x / r.face_area_m2)
    }

    /// Mean of the requested quantity over the root's face, clamped at 0: light is never negative,
    /// but a source whose higher-order radiosity dips below 0 near a shadow edge sends a little
    /// negative light, and a face in full shadow can end a hair below 0 (1e-6 of the scene's mean
    /// on the Red Eclipse level).
    pub fn mean_value(&self, root: usize) -> Rgb {
        let indirect = self.params.indirect_only;
        let mean_h = self.face_mean_irradiance(root, indirect, true);
        let reflected = match self.params.quantity {
            Quantity::Radiance => self.face_mean_reflected(root, indirect, true),
            Quantity::Irradiance => [0.0; 3],
        };
        // (`if`, not `max`: a NaN must stay visible.)
        self.quantity(mean_h, reflected, self.roots[root].exitance)
            .map(|v| if v < 0.0 { 0.0 } else { v })
    }

    /// Mean radiosity B over the root's face (emission included), W/m^2.
    pub fn mean_radiosity(&self, root: usize) -> Rgb {
        let r = &self.roots[root];
        // Unclamped: the raw integral, so checks of it see what the solver computed.
        let reflected = self.face_mean_reflected(root, false, false);
        [0, 1, 2].map(|c| r.exitance[c] + reflected[c])
    }
}
