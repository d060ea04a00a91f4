//! Reference values at probe points and the error metric they define: the data sets of
//! `tests/data/reference/` (copied from `../shared/reference/`, whose README is there too), each
//! the outgoing radiance of an independent Monte Carlo path tracer at 400 surface points, and the
//! CIE 171:2006 analytic cases of `tests/data/cie171/` (exact illuminance at points).
//!
//! Owns [`ReferenceSet`], [`ReferenceError`], [`CieCase`], [`CieError`] and [`DataSet`] (either
//! kind, with its scene, its probes and the quantity to solve for: what `tests/reference.rs`,
//! `tests/cie171.rs`, `wavrad bench sweep` and `benches/accuracy.rs` share). The metric, per
//! channel `c`: `rms_c = sqrt(mean_i (L_i,c - Lref_i,c)^2)`, `nrms = mean_c (rms_c / mean_i
//! Lref_i,c)`; the worst point is the largest channel-averaged `|L - Lref|` over the channel-averaged
//! mean (relative errors at dark points mean nothing). For a CIE case the same nrms on illuminance
//! (`E = pi x` the channel-averaged probe value), and the worst point is the largest relative error
//! (every expected value there is positive). Pinned by `the_metric_is_rms_over_mean_per_channel_averaged`
//! and `a_cie_case_is_scored_on_illuminance`.
//!
//! Invariants: a set's points are in the order of its probes; a probe the solver could not place
//! makes the error undefined (`None`), it is never skipped.

use serde::Deserialize;
use std::path::{Path, PathBuf};

use crate::output::probes::{ProbePoint, ProbeValue};

/// Reads and parses a JSON file; the error names the file.
pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

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
    /// The largest channel-averaged absolute error over the channel-averaged reference mean.
    pub worst: f64,
    /// The index (probe order) of that point.
    pub worst_point: usize,
}

impl ReferenceSet {
    /// Reads `dir/reference.json`.
    pub fn load(dir: &Path) -> Result<Self, String> {
        let path = dir.join("reference.json");
        let set: ReferenceSet = read_json(&path)?;
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
        let mut grey_mean = 0.0;
        for c in 0..3 {
            let (mut sq, mut mean) = (0.0, 0.0);
            for (v, r) in values.iter().zip(&self.points) {
                sq += (v[c] - r.l[c]) * (v[c] - r.l[c]);
                mean += r.l[c];
            }
            rms[c] = (sq / n).sqrt();
            nrms += rms[c] / (mean / n) / 3.0;
            grey_mean += mean / n / 3.0;
        }
        let (mut worst, mut worst_point) = (0.0f64, 0);
        for (i, (v, r)) in values.iter().zip(&self.points).enumerate() {
            let off = (0..3).map(|c| (v[c] - r.l[c]).abs()).sum::<f64>() / 3.0 / grey_mean;
            if off > worst {
                (worst, worst_point) = (off, i);
            }
        }
        Some(ReferenceError {
            rms,
            nrms,
            worst,
            worst_point,
        })
    }
}

/// One point of a CIE case: its label, the exact illuminance and, where the case gives one, the
/// area it stands for in the case's area-weighted mean.
#[derive(Debug, Clone, Deserialize)]
pub struct CiePoint {
    pub label: String,
    #[serde(rename = "E_lux")]
    pub e_lux: f64,
    pub w_m2: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
struct CieGlobal {
    expected_mean_total_lux: Option<f64>,
}

/// A CIE 171:2006 case: `expected.json` of one folder of `tests/data/cie171/` (its scene is the
/// folder's `scene.gltf`, its probes `probes.json`, solved for irradiance).
#[derive(Debug, Clone, Deserialize)]
pub struct CieCase {
    pub points: Vec<CiePoint>,
    global: Option<CieGlobal>,
}

/// A solution's error against a [`CieCase`].
#[derive(Debug, Clone, PartialEq)]
pub struct CieError {
    /// RMS of the illuminance error over the mean expected illuminance.
    pub nrms: f64,
    /// The signed relative error of the point with the largest one.
    pub worst: f64,
    pub worst_label: String,
    /// The signed relative error of the area-weighted mean, where the case defines one.
    pub global: Option<f64>,
}

impl CieCase {
    /// Reads `dir/expected.json`.
    pub fn load(dir: &Path) -> Result<Self, String> {
        let path = dir.join("expected.json");
        let case: CieCase = read_json(&path)?;
        if case.points.is_empty() || case.points.iter().any(|p| p.e_lux <= 0.0) {
            return Err(format!(
                "{}: no points, or an expected value not positive",
                path.display()
            ));
        }
        Ok(case)
    }

    /// The error of `values` (irradiance probe values, in probe order); `None` when a probe has no
    /// value or the counts differ.
    pub fn error(&self, values: &[ProbeValue]) -> Option<CieError> {
        let l: Option<Vec<[f64; 3]>> = values.iter().map(|v| v.l).collect();
        self.error_of(&l?)
    }

    fn error_of(&self, values: &[[f64; 3]]) -> Option<CieError> {
        if values.len() != self.points.len() {
            return None;
        }
        let n = values.len() as f64;
        let (mut sq, mut mean) = (0.0, 0.0);
        let (mut worst, mut worst_label) = (0.0f64, String::new());
        let (mut weight, mut weighted) = (0.0, 0.0);
        for (v, p) in values.iter().zip(&self.points) {
            let lux = std::f64::consts::PI * (v[0] + v[1] + v[2]) / 3.0;
            sq += (lux - p.e_lux) * (lux - p.e_lux);
            mean += p.e_lux;
            let rel = (lux - p.e_lux) / p.e_lux;
            if rel.abs() > worst.abs() || worst_label.is_empty() {
                (worst, worst_label) = (rel, p.label.clone());
            }
            if let Some(w) = p.w_m2 {
                weight += w;
                weighted += w * lux;
            }
        }
        let global = self
            .global
            .as_ref()
            .and_then(|g| g.expected_mean_total_lux)
            .filter(|_| weight > 0.0)
            .map(|want| (weighted / weight - want) / want);
        Some(CieError {
            nrms: (sq / n).sqrt() / (mean / n),
            worst,
            worst_label,
            global,
        })
    }
}

/// What a [`DataSet`] is measured against.
#[derive(Debug, Clone)]
pub enum Truth {
    MonteCarlo(ReferenceSet),
    Cie(CieCase),
}

/// A solution's error against a [`DataSet`], either kind: nrms and the worst point (an absolute
/// error over the mean for a Monte Carlo set, a relative error for a CIE case), with its label.
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    pub nrms: f64,
    pub worst: f64,
    pub worst_label: String,
}

/// A folder with a scene, probes and the values they should read: a Monte Carlo reference set
/// (`reference.json`) or a CIE case (`expected.json`).
#[derive(Debug, Clone)]
pub struct DataSet {
    /// The folder's name.
    pub name: String,
    pub scene: PathBuf,
    pub probes: PathBuf,
    /// Probe values hold irradiance (CIE cases) rather than radiance.
    pub irradiance: bool,
    pub truth: Truth,
}

impl DataSet {
    /// Opens `dir`; the scene of a Monte Carlo set is looked up under `repo` ([`ReferenceSet::scene_in`]).
    pub fn open(dir: &Path, repo: &Path) -> Result<Self, String> {
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let probes = dir.join("probes.json");
        if dir.join("reference.json").exists() {
            let set = ReferenceSet::load(dir)?;
            Ok(DataSet {
                name,
                scene: set.scene_in(repo),
                probes,
                irradiance: false,
                truth: Truth::MonteCarlo(set),
            })
        } else if dir.join("expected.json").exists() {
            Ok(DataSet {
                name,
                scene: dir.join("scene.gltf"),
                probes,
                irradiance: true,
                truth: Truth::Cie(CieCase::load(dir)?),
            })
        } else {
            Err(format!(
                "{}: neither reference.json nor expected.json",
                dir.display()
            ))
        }
    }

    /// The error of `values` (in probe order); `None` when a probe has no value.
    pub fn score(&self, values: &[ProbeValue]) -> Option<Score> {
        match &self.truth {
            Truth::MonteCarlo(set) => set.error(values).map(|e| Score {
                nrms: e.nrms,
                worst: e.worst,
                worst_label: format!("#{}", e.worst_point),
            }),
            Truth::Cie(case) => case.error(values).map(|e| Score {
                nrms: e.nrms,
                worst: e.worst,
                worst_label: e.worst_label,
            }),
        }
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
        // Channel-averaged |errors|: (1 + 0 + 2) / 3 and (1 + 0 + 0) / 3 over the grey mean 5 / 3.
        assert!((e.worst - 0.6).abs() < 1e-15);
        assert_eq!(e.worst_point, 0);
        assert_eq!(s.error_of(&[[0.0; 3]]), None);
        let missing = ProbeValue {
            l: None,
            face: None,
            error: Some("not on a surface".into()),
        };
        assert_eq!(s.error(&[missing.clone(), missing]), None);
    }

    #[test]
    fn a_cie_case_is_scored_on_illuminance() {
        let case = CieCase {
            points: [("A", 10.0, Some(1.0)), ("B", 20.0, Some(3.0))]
                .iter()
                .map(|&(label, e_lux, w_m2)| CiePoint {
                    label: label.into(),
                    e_lux,
                    w_m2,
                })
                .collect(),
            global: Some(CieGlobal {
                expected_mean_total_lux: Some(17.5),
            }),
        };
        let pi = std::f64::consts::PI;
        // A reads 11 lx (+10 %), B 19 lx (-5 %).
        let e = case
            .error_of(&[[11.0 / pi; 3], [19.0 / pi; 3]])
            .expect("same length");
        assert!((e.nrms - 1.0 / 15.0).abs() < 1e-12);
        assert!((e.worst - 0.1).abs() < 1e-12);
        assert_eq!(e.worst_label, "A");
        // (11 + 3 x 19) / 4 = 17 against 17.5.
        assert!((e.global.expect("weights given") + 0.5 / 17.5).abs() < 1e-12);
    }
}
