//! Reference radiance at probe points and the error metric it defines: the data sets of
//! `tests/data/reference/` (copied from `../shared/reference/`, whose README is there too), each
//! the outgoing radiance of an independent Monte Carlo path tracer at 400 surface points.
//!
//! Owns [`ReferenceSet`] and [`ReferenceError`]. The metric, per channel `c`:
//! `rms_c = sqrt(mean_i (L_i,c - Lref_i,c)^2)`, `nrms = mean_c (rms_c / mean_i Lref_i,c)`.
//!
//! Invariants: a set's points are in the order of its probes; a probe the solver could not place
//! makes the error undefined (`None`), it is never skipped.

use serde::Deserialize;
use std::path::{Path, PathBuf};

use crate::output::probes::{ProbePoint, ProbeValue};

/// One reference point: a surface point, the normal of the side asked about, and its radiance.
#[derive(Debug, Clone, Deserialize)]
pub struct ReferencePoint {
    pub p: [f64; 3],
    pub n: [f64; 3],
    #[serde(rename = "L")]
    pub l: [f64; 3],
}

#[derive(Debug, Clone, Deserialize)]
struct Noise {
    nrms_noise_floor: f64,
}

/// A data set: `reference.json` of one folder.
#[derive(Debug, Clone, Deserialize)]
pub struct ReferenceSet {
    /// The scene file, relative to the `shared/` folder the data came from.
    pub scene: String,
    pub points: Vec<ReferencePoint>,
    noise: Noise,
}

/// A solution's error against a [`ReferenceSet`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceError {
    /// Absolute RMS error per channel, in the units of L.
    pub rms: [f64; 3],
    /// RMS error over the reference mean, averaged over channels.
    pub nrms: f64,
}

impl ReferenceSet {
    /// Reads `dir/reference.json`.
    pub fn load(dir: &Path) -> Result<Self, String> {
        let path = dir.join("reference.json");
        let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let set: ReferenceSet =
            serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        if set.points.is_empty() {
            return Err(format!("{}: no points", path.display()));
        }
        Ok(set)
    }

    /// The repository's copy of the set's scene (`repo` is the repository root): the samples in
    /// `scenes/`, the other scenes in `tests/data/` (the path under `shared/scenes/` kept).
    pub fn scene_in(&self, repo: &Path) -> PathBuf {
        let sample = repo.join(&self.scene);
        if sample.exists() {
            return sample;
        }
        repo.join("tests/data")
            .join(self.scene.strip_prefix("scenes/").unwrap_or(&self.scene))
    }

    /// The probe points, in order (the same as the folder's `probes.json`).
    pub fn probes(&self) -> Vec<ProbePoint> {
        self.points
            .iter()
            .map(|r| ProbePoint { p: r.p, n: r.n })
            .collect()
    }

    /// The nrms a perfect solver would show against this set, from the reference's own noise.
    pub fn noise_floor(&self) -> f64 {
        self.noise.nrms_noise_floor
    }

    /// The error of `values` (in probe order); `None` when a probe has no value or the counts differ.
    pub fn error(&self, values: &[ProbeValue]) -> Option<ReferenceError> {
        let l: Option<Vec<[f64; 3]>> = values.iter().map(|v| v.l).collect();
        self.error_of(&l?)
    }

    fn error_of(&self, values: &[[f64; 3]]) -> Option<ReferenceError> {
        if values.len() != self.points.len() {
            return None;
        }
        let n = values.len() as f64;
        let mut rms = [0.0; 3];
        let mut nrms = 0.0;
        for c in 0..3 {
            let (mut sq, mut mean) = (0.0, 0.0);
            for (v, r) in values.iter().zip(&self.points) {
                sq += (v[c] - r.l[c]) * (v[c] - r.l[c]);
                mean += r.l[c];
            }
            rms[c] = (sq / n).sqrt();
            nrms += rms[c] / (mean / n) / 3.0;
        }
        Some(ReferenceError { rms, nrms })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(ls: &[[f64; 3]]) -> ReferenceSet {
        ReferenceSet {
            scene: String::new(),
            points: ls
                .iter()
                .map(|&l| ReferencePoint {
                    p: [0.0; 3],
                    n: [0.0, 0.0, 1.0],
                    l,
                })
                .collect(),
            noise: Noise {
                nrms_noise_floor: 0.0,
            },
        }
    }

    #[test]
    fn the_metric_is_rms_over_mean_per_channel_averaged() {
        let s = set(&[[1.0, 2.0, 0.0], [3.0, 2.0, 2.0]]);
        // Errors: red (+1, -1), green (0, 0), blue (+2, 0).
        let e = s
            .error_of(&[[2.0, 2.0, 2.0], [2.0, 2.0, 2.0]])
            .expect("same length");
        assert_eq!(e.rms, [1.0, 0.0, 2f64.sqrt()]);
        // Means: 2, 2, 1.
        let expected = (1.0 / 2.0 + 0.0 + 2f64.sqrt() / 1.0) / 3.0;
        assert!((e.nrms - expected).abs() < 1e-15);
        assert_eq!(s.error_of(&[[0.0; 3]]), None);
        let missing = ProbeValue {
            l: None,
            face: None,
            error: Some("not on a surface".into()),
        };
        assert_eq!(s.error(&[missing.clone(), missing]), None);
    }
}
