//! Probes: the solution evaluated at user points (docs/contract.md, "Probe points file").
//!
//! A probe is located on the element root whose plane passes within `PROBE_DISTANCE_REL * diagonal`
//! of the point, whose side's normal agrees with the probe normal, and whose shape contains the
//! point's projection (within the same tolerance); the nearest such root wins. A point on the back
//! of a single-sided face gets 0 in radiance (it has no radiosity side there).

use crate::solver::{Quantity, Solution};
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// Probes farther than this fraction of the scene diagonal from every surface are not found.
pub const PROBE_DISTANCE_REL: f64 = 1e-4;
/// Most probes accepted in one request.
pub const MAX_PROBES: usize = 1_000_000;

#[derive(Debug, Clone, Deserialize)]
pub struct ProbePoint {
    pub p: [f64; 3],
    pub n: [f64; 3],
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ProbeValue {
    #[serde(rename = "L")]
    pub l: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub face: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Parses and checks a probe points file.
pub fn parse_probes(bytes: &[u8]) -> Result<Vec<ProbePoint>, String> {
    let probes: Vec<ProbePoint> = serde_json::from_slice(bytes).map_err(|e| {
        format!("probe points must be [{{\"p\":[x,y,z],\"n\":[nx,ny,nz]}}, ...]: {e}")
    })?;
    if probes.len() > MAX_PROBES {
        return Err(format!(
            "{} probes, more than the limit of {MAX_PROBES}",
            probes.len()
        ));
    }
    for (i, pr) in probes.iter().enumerate() {
        if pr.p.iter().chain(&pr.n).any(|x| !x.is_finite()) {
            return Err(format!("probe {i}: coordinates must be finite numbers"));
        }
        if DVec3::from(pr.n).length() == 0.0 {
            return Err(format!("probe {i}: the normal n is zero"));
        }
    }
    Ok(probes)
}

/// Evaluates the requested quantity at every probe.
pub fn evaluate_probes(
    solution: &Solution,
    probes: &[ProbePoint],
    diagonal: f64,
) -> Vec<ProbeValue> {
    let tol = PROBE_DISTANCE_REL * diagonal;
    probes
        .iter()
        .map(|pr| {
            let x = DVec3::from(pr.p);
            let n = DVec3::from(pr.n).normalize();
            value_at_point(solution, 0..solution.roots.len(), x, n, tol, diagonal)
        })
        .collect()
}

/// The probe rule (module header) for the point `x` seen from the side `n` (unit), among the
/// roots `candidates`, each within `tol` of `x`: every probe, and the preview at the surface a
/// pixel sees (`output::preview`, with the hit face's roots), go through it.
pub(crate) fn value_at_point(
    solution: &Solution,
    candidates: impl IntoIterator<Item = usize>,
    x: DVec3,
    n: DVec3,
    tol: f64,
    diagonal: f64,
) -> ProbeValue {
    let mut best: Option<(f64, usize, DVec2, bool)> = None;
    for i in candidates {
        let r = &solution.roots[i];
        let (st, dist, outside) = r.locate(x);
        if dist > tol || outside > tol {
            continue;
        }
        let same_side = r.normal.dot(n) > 0.0;
        let score = dist + outside + if same_side { 0.0 } else { 1.0 * diagonal };
        if best.is_none_or(|b| score < b.0) {
            best = Some((score, i, st, same_side));
        }
    }
    match best {
        Some((_, i, st, true)) => ProbeValue {
            l: Some(solution.value_at(i, st)),
            face: Some(solution.roots[i].face.0),
            error: None,
        },
        // Only the other side of a single-sided face is here: it reflects nothing.
        Some((_, i, _, false)) => ProbeValue {
            l: Some([0.0; 3]),
            face: Some(solution.roots[i].face.0),
            error: match solution.params.quantity {
                Quantity::Irradiance => Some("the back of a single-sided face: its irradiance is not computed in this version".into()),
                Quantity::Radiance => None,
            },
        },
        None => ProbeValue {
            l: None,
            face: None,
            error: Some(format!("no surface within {tol:.3e} m of this point")),
        },
    }
}
