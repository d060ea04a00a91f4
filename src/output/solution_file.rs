//! `solution.bin`: a solved job's solution on disk, so that probes can be evaluated on it after
//! the process that solved it is gone (the service answers `POST /v1/jobs/{id}/probes` from it
//! across restarts).
//!
//! Only what evaluation needs is stored: the parameters that change a value (order, quantity,
//! indirect-only, and the domain mode that decides the roots), and per root its hierarchy's nodes
//! (map, depth, first child) with the coefficient arrays `h` and `hd`. The element roots are not
//! stored: the job layer rebuilds them from the job's scene and [`SavedSolution::attach`] checks
//! them against a fingerprint stored in the file and recomputes the covers of extended roots
//! ([`Solution::from_saved`]). This module only encodes and decodes.
//!
//! Format (little-endian), version [`FORMAT_VERSION`]:
//! ```text
//! magic "WAVRSOL\0" | version u32 | order u8 | quantity u8 (0 radiance, 1 irradiance)
//! | indirect_only u8 | domain u8 (0 extended, 1 tessellated) | roots u64 | roots fingerprint u64
//! | per root: shape u8 (0 triangle, 1 parallelogram) | functions per node u32 | nodes u64
//! |           per node: o.x o.y e1.x e1.y e2.x e2.y f64, depth u8, first_child u32
//! |           h: nodes * functions * 3 f64 | hd: the same
//! | checksum u64 (FNV-1a of every byte before it)
//! ```
//! A file that does not parse, fails its checksum, has another version, or does not match the
//! scene's roots is refused with a [`SolutionFileError`]; reading never panics on its content.

use crate::domain::{DomainMode, ElementRoot, Shape, Side};
use crate::fsutil::write_atomic_with;
use crate::solver::basis::ChildMap;
use crate::solver::hierarchy::{Hierarchy, Node};
use crate::solver::{Quantity, Solution, SolverParams};
use glam::DVec2;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// File name of the saved solution in a job directory.
pub const SOLUTION_FILE: &str = "solution.bin";
/// The first bytes of every solution file.
pub const MAGIC: [u8; 8] = *b"WAVRSOL\0";
/// The format this version writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// Bytes of one stored node: six f64, depth u8, first child u32.
const NODE_BYTES: usize = 6 * 8 + 1 + 4;

/// Why a solution file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SolutionFileError {
    /// Reading the file failed (`NotFound`: there is none).
    #[error("reading the saved solution failed: {0}")]
    Io(#[from] io::Error),
    #[error("not a wavrad solution file (wrong magic)")]
    BadMagic,
    #[error("solution file format version {found}; this version reads version {FORMAT_VERSION}")]
    Version { found: u32 },
    #[error("the saved solution is corrupt: {0}")]
    Corrupt(String),
    #[error(
        "the saved solution does not match the scene's elements as this version builds them: {0}"
    )]
    Mismatch(String),
}

impl SolutionFileError {
    /// Whether the file is simply not there.
    pub fn is_missing(&self) -> bool {
        matches!(self, SolutionFileError::Io(e) if e.kind() == io::ErrorKind::NotFound)
    }
}

/// FNV-1a, 64 bits.
#[derive(Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    const fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// A writer that hashes what passes through it.
struct Hashing<W> {
    inner: W,
    hash: Fnv,
}

impl<W: Write> Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

fn shape_code(shape: Shape) -> u8 {
    match shape {
        Shape::Triangle => 0,
        Shape::Parallelogram => 1,
    }
}

fn domain_code(mode: DomainMode) -> u8 {
    match mode {
        DomainMode::Extended => 0,
        DomainMode::Tessellated => 1,
    }
}

/// A fingerprint of the roots: what identifies each one and what evaluation reads from it
/// (face, side, shape, frame, normal, material, reflectance, emission, areas, extended or not).
fn roots_fingerprint(roots: &[ElementRoot]) -> u64 {
    let mut h = Fnv::new();
    let f64s = |h: &mut Fnv, xs: &[f64]| {
        for x in xs {
            h.update(&x.to_le_bytes());
        }
    };
    for r in roots {
        h.update(&r.face.0.to_le_bytes());
        h.update(&[
            matches!(r.side, Side::Back) as u8,
            shape_code(r.shape),
            r.mask.is_some() as u8,
        ]);
        h.update(&r.material.to_le_bytes());
        let f = &r.frame;
        for v in [f.origin, f.u, f.v, r.normal] {
            f64s(&mut h, &v.to_array());
        }
        f64s(&mut h, &r.rho);
        f64s(&mut h, &r.exitance);
        f64s(&mut h, &[r.area_m2, r.face_area_m2]);
    }
    h.0
}

/// Writes `solution` (solved with domain mode `mode`) in the solution file format.
pub fn encode(solution: &Solution, mode: DomainMode, out: impl Write) -> io::Result<()> {
    let mut w = Hashing {
        inner: out,
        hash: Fnv::new(),
    };
    let p = &solution.params;
    w.write_all(&MAGIC)?;
    w.write_all(&FORMAT_VERSION.to_le_bytes())?;
    let order = u8::try_from(p.order).map_err(io::Error::other)?;
    let quantity = match p.quantity {
        Quantity::Radiance => 0u8,
        Quantity::Irradiance => 1,
    };
    w.write_all(&[order, quantity, p.indirect_only as u8, domain_code(mode)])?;
    w.write_all(&(solution.roots.len() as u64).to_le_bytes())?;
    w.write_all(&roots_fingerprint(&solution.roots).to_le_bytes())?;
    for (r, h) in solution.roots.iter().zip(&solution.hierarchies) {
        w.write_all(&[shape_code(r.shape)])?;
        let len = u32::try_from(h.len).map_err(io::Error::other)?;
        w.write_all(&len.to_le_bytes())?;
        w.write_all(&(h.nodes.len() as u64).to_le_bytes())?;
        for n in &h.nodes {
            let m = &n.map;
            for x in [m.o.x, m.o.y, m.e1.x, m.e1.y, m.e2.x, m.e2.y] {
                w.write_all(&x.to_le_bytes())?;
            }
            w.write_all(&[n.depth])?;
            w.write_all(&n.first_child.to_le_bytes())?;
        }
        for array in [&h.h, &h.hd] {
            for c in array.iter().flatten() {
                w.write_all(&c.to_le_bytes())?;
            }
        }
    }
    let checksum = w.hash.0;
    w.inner.write_all(&checksum.to_le_bytes())?;
    w.inner.flush()
}

/// Saves `solution` to `path` atomically (temporary file, fsync, rename, fsync of the directory).
pub fn save(path: &Path, solution: &Solution, mode: DomainMode) -> io::Result<()> {
    write_atomic_with(path, |tmp| {
        let file = std::fs::File::create(tmp)?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        encode(solution, mode, &mut out)?;
        out.flush()
    })
}

/// Bounds-checked little-endian reads.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], SolutionFileError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| SolutionFileError::Corrupt("truncated".into()))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], SolutionFileError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, SolutionFileError> {
        Ok(self.array::<1>()?[0])
    }
    fn u32(&mut self) -> Result<u32, SolutionFileError> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    fn u64(&mut self) -> Result<u64, SolutionFileError> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    fn f64(&mut self) -> Result<f64, SolutionFileError> {
        Ok(f64::from_le_bytes(self.array()?))
    }
    fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }
    /// A count of items of `item_bytes` each that must fit in what is left.
    fn count(&mut self, item_bytes: usize, what: &str) -> Result<usize, SolutionFileError> {
        let n = self.u64()?;
        usize::try_from(n)
            .ok()
            .filter(|&n| {
                n.checked_mul(item_bytes)
                    .is_some_and(|b| b <= self.remaining())
            })
            .ok_or_else(|| {
                SolutionFileError::Corrupt(format!("{what}: count {n} exceeds the file"))
            })
    }
}

/// What the file holds before the roots are rebuilt.
#[derive(Debug)]
struct Parsed {
    params: SolverParams,
    mode: DomainMode,
    fingerprint: u64,
    shapes: Vec<u8>,
    hierarchies: Vec<Hierarchy>,
}

fn parse(bytes: &[u8]) -> Result<Parsed, SolutionFileError> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(SolutionFileError::BadMagic);
    }
    let mut r = Reader { bytes, at: 8 };
    let version = r.u32()?;
    if version != FORMAT_VERSION {
        return Err(SolutionFileError::Version { found: version });
    }
    let Some(body_len) = bytes.len().checked_sub(8).filter(|&n| n >= r.at) else {
        return Err(SolutionFileError::Corrupt("truncated".into()));
    };
    let (body, trailer) = bytes.split_at(body_len);
    let mut hash = Fnv::new();
    hash.update(body);
    let mut stored = [0u8; 8];
    stored.copy_from_slice(trailer);
    if u64::from_le_bytes(stored) != hash.0 {
        return Err(SolutionFileError::Corrupt(
            "checksum mismatch (truncated or damaged)".into(),
        ));
    }
    let mut r = Reader {
        bytes: body,
        at: r.at,
    };
    let [order, quantity, indirect_only, domain] = r.array::<4>()?;
    if !(1..=3).contains(&order) {
        return Err(SolutionFileError::Corrupt(format!("order {order}")));
    }
    let quantity = match quantity {
        0 => Quantity::Radiance,
        1 => Quantity::Irradiance,
        q => return Err(SolutionFileError::Corrupt(format!("quantity code {q}"))),
    };
    let mode = match domain {
        0 => DomainMode::Extended,
        1 => DomainMode::Tessellated,
        d => return Err(SolutionFileError::Corrupt(format!("domain code {d}"))),
    };
    if indirect_only > 1 {
        return Err(SolutionFileError::Corrupt("indirect_only flag".into()));
    }
    // Every root takes at least its own header (shape, functions, node count).
    let roots = r.count(1 + 4 + 8, "roots")?;
    let fingerprint = r.u64()?;
    let mut shapes = Vec::with_capacity(roots);
    let mut hierarchies = Vec::with_capacity(roots);
    for i in 0..roots {
        let shape = r.u8()?;
        if shape > 1 {
            return Err(SolutionFileError::Corrupt(format!(
                "root {i}: shape code {shape}"
            )));
        }
        let len = r.u32()? as usize;
        if len == 0 || len > crate::solver::basis::MAX_FUNCTIONS {
            return Err(SolutionFileError::Corrupt(format!(
                "root {i}: {len} functions"
            )));
        }
        // Per node: the node and two arrays of `len` RGB coefficients.
        let nodes = r.count(NODE_BYTES + 2 * len * 3 * 8, "nodes")?;
        if nodes == 0 {
            return Err(SolutionFileError::Corrupt(format!("root {i} has no nodes")));
        }
        let mut h = Hierarchy::new(len);
        h.nodes.clear();
        for _ in 0..nodes {
            let mut m = [0.0; 6];
            for x in &mut m {
                *x = r.f64()?;
            }
            let depth = r.u8()?;
            let first_child = r.u32()?;
            h.nodes.push(Node {
                map: ChildMap {
                    o: DVec2::new(m[0], m[1]),
                    e1: DVec2::new(m[2], m[3]),
                    e2: DVec2::new(m[4], m[5]),
                },
                depth,
                first_child,
            });
        }
        let read_array = |r: &mut Reader| -> Result<Vec<[f64; 3]>, SolutionFileError> {
            let mut a = Vec::with_capacity(nodes * len);
            for _ in 0..nodes * len {
                let c = [r.f64()?, r.f64()?, r.f64()?];
                if !c.iter().all(|x| x.is_finite()) {
                    return Err(SolutionFileError::Corrupt(format!(
                        "root {i}: a non-finite coefficient"
                    )));
                }
                a.push(c);
            }
            Ok(a)
        };
        h.h = read_array(&mut r)?;
        h.hd = read_array(&mut r)?;
        shapes.push(shape);
        hierarchies.push(h);
    }
    if r.remaining() != 0 {
        return Err(SolutionFileError::Corrupt(format!(
            "{} bytes after the last root",
            r.remaining()
        )));
    }
    Ok(Parsed {
        params: SolverParams {
            order: order as usize,
            quantity,
            indirect_only: indirect_only == 1,
            ..SolverParams::default()
        },
        mode,
        fingerprint,
        shapes,
        hierarchies,
    })
}

/// A solution file parsed and checked on its own, waiting for the element roots it was solved
/// on. The job layer rebuilds them from the job's scene with the file's [`SavedSolution::mode`]
/// (`pipeline::prepare` is deterministic: fixed hashers and seeds, ordered reductions) and hands
/// them to [`SavedSolution::attach`], which checks them against the file.
#[derive(Debug)]
pub struct SavedSolution(Parsed);

impl SavedSolution {
    /// The domain mode the saved roots were built with.
    pub fn mode(&self) -> DomainMode {
        self.0.mode
    }

    /// The solution, on `roots` rebuilt from the job's scene; refused when they are not the
    /// roots the file was saved with (count, shapes, fingerprint of geometry and materials).
    pub fn attach(self, roots: Vec<ElementRoot>) -> Result<Solution, SolutionFileError> {
        let parsed = self.0;
        if roots.len() != parsed.hierarchies.len() {
            return Err(SolutionFileError::Mismatch(format!(
                "{} element roots saved, {} rebuilt",
                parsed.hierarchies.len(),
                roots.len()
            )));
        }
        if let Some(i) = (0..roots.len()).find(|&i| shape_code(roots[i].shape) != parsed.shapes[i])
        {
            return Err(SolutionFileError::Mismatch(format!(
                "root {i} has another shape"
            )));
        }
        if roots_fingerprint(&roots) != parsed.fingerprint {
            return Err(SolutionFileError::Mismatch(
                "the roots' geometry or materials differ".into(),
            ));
        }
        Solution::from_saved(roots, parsed.hierarchies, parsed.params)
            .map_err(SolutionFileError::Corrupt)
    }
}

/// Parses and checks a saved solution (magic, version, checksum, structure).
pub fn decode(bytes: &[u8]) -> Result<SavedSolution, SolutionFileError> {
    parse(bytes).map(SavedSolution)
}

/// Reads and decodes the solution file at `path`.
pub fn read(path: &Path) -> Result<SavedSolution, SolutionFileError> {
    decode(&std::fs::read(path)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::probes::{evaluate_probes, ProbePoint};
    use crate::pipeline::{bake, prepare};
    use crate::scene::gltf_writer::SceneBuilder;
    use crate::scene::Scene;
    use crate::scene::{load_scene, ExternalFiles};
    use glam::DVec3;
    use std::sync::atomic::AtomicBool;

    /// A holed square emitter (an extended face: four strips around a square hole) over a full
    /// square receiver and a triangle (native roots), all single-sided.
    fn scene() -> Scene {
        let mut b = SceneBuilder::new();
        let recv = b.material([0.7, 0.5, 0.3], [0.0; 3], false);
        let emit = b.material([0.4; 3], [1.0, 0.8, 0.6], false);
        let side = b.material([0.6; 3], [0.0; 3], true);
        b.quad(recv, DVec3::new(-0.5, -0.5, 0.0), DVec3::X, DVec3::Y, 1);
        let (o, u, v) = (DVec3::new(-0.5, -0.5, 1.0), DVec3::Y, DVec3::X);
        b.quad(emit, o, u, v * 0.25, 1);
        b.quad(emit, o + v * 0.75, u, v * 0.25, 1);
        b.quad(emit, o + v * 0.25, u * 0.25, v * 0.5, 1);
        b.quad(emit, o + v * 0.25 + u * 0.75, u * 0.25, v * 0.5, 1);
        b.mesh(
            side,
            &[
                DVec3::new(-0.5, -0.5, 0.1),
                DVec3::new(-0.5, 0.5, 0.1),
                DVec3::new(-0.5, 0.0, 0.9),
            ],
            &[0, 1, 2],
        );
        load_scene(&b.to_glb(), &ExternalFiles::Refuse, 1000).expect("scene loads")
    }

    fn solve(scene: &Scene, mode: DomainMode, order: usize, quantity: Quantity) -> Solution {
        let params = SolverParams {
            order,
            quantity,
            indirect_only: quantity == Quantity::Irradiance,
            tolerance: 1e-4,
            ..SolverParams::default()
        };
        bake(scene, mode, params, &AtomicBool::new(false), &mut |_| {})
            .expect("bakes")
            .1
    }

    /// What the job layer does with a file: decode, rebuild the roots, attach them.
    #[derive(Debug)]
    struct Loaded {
        solution: Solution,
        diagonal: f64,
    }

    fn decode_for(bytes: &[u8], scene: &Scene) -> Result<Loaded, SolutionFileError> {
        let saved = decode(bytes)?;
        let prepared = prepare(scene, saved.mode());
        Ok(Loaded {
            solution: saved.attach(prepared.roots)?,
            diagonal: prepared.diagonal,
        })
    }

    fn encoded(solution: &Solution, mode: DomainMode) -> Vec<u8> {
        let mut bytes = Vec::new();
        encode(solution, mode, &mut bytes).unwrap();
        bytes
    }

    /// Probe points over every root (a grid of reference points mapped to the world), both sides.
    fn probes(solution: &Solution) -> Vec<ProbePoint> {
        let mut out = Vec::new();
        for r in &solution.roots {
            for i in 0..7 {
                for j in 0..7 {
                    let (s, t) = ((i as f64 + 0.3) / 7.0, (j as f64 + 0.6) / 7.0);
                    if r.shape == Shape::Triangle && s + t > 1.0 {
                        continue;
                    }
                    let p = r.frame.point(DVec2::new(s, t));
                    for n in [r.normal, -r.normal] {
                        out.push(ProbePoint {
                            p: p.to_array(),
                            n: n.to_array(),
                        });
                    }
                }
            }
        }
        out
    }

    #[test]
    fn a_saved_solution_gives_identical_values() {
        let scene = scene();
        for (mode, order, quantity) in [
            (DomainMode::Extended, 2, Quantity::Radiance),
            (DomainMode::Extended, 3, Quantity::Irradiance),
            (DomainMode::Tessellated, 1, Quantity::Radiance),
        ] {
            let solved = solve(&scene, mode, order, quantity);
            if mode == DomainMode::Extended {
                assert!(
                    solved.roots.iter().any(|r| r.mask.is_some())
                        && solved.roots.iter().any(|r| r.mask.is_none()),
                    "extended and native roots"
                );
                assert!(solved.hierarchies.iter().any(|h| h.nodes.len() > 1));
            }
            let bytes = encoded(&solved, mode);
            let loaded = decode_for(&bytes, &scene).expect("decodes");
            let back = &loaded.solution;
            assert_eq!(loaded.diagonal, scene.diagonal());
            assert_eq!(back.params.order, order);
            assert_eq!(back.params.quantity, quantity);
            assert_eq!(back.roots.len(), solved.roots.len());
            for (a, b) in solved.hierarchies.iter().zip(&back.hierarchies) {
                assert_eq!(a.nodes.len(), b.nodes.len());
                assert_eq!(a.h, b.h);
                assert_eq!(a.hd, b.hd);
                assert_eq!(a.covers.len(), b.covers.len());
                for (x, y) in a.covers.iter().zip(&b.covers) {
                    assert_eq!(x.moments, y.moments);
                    assert_eq!(x.alpha, y.alpha);
                }
            }
            let points = probes(&solved);
            assert!(points.len() > 100);
            let before = evaluate_probes(&solved, &points, scene.diagonal());
            let after = evaluate_probes(back, &points, loaded.diagonal);
            assert_eq!(before, after, "{mode:?} M{order}");
            assert!(before.iter().any(|v| v.l.is_some_and(|l| l[0] > 0.0)));
            for i in 0..solved.roots.len() {
                assert_eq!(solved.mean_value(i), back.mean_value(i));
            }
            // Encoding the loaded solution gives the same bytes.
            assert_eq!(encoded(back, mode), bytes);
        }
    }

    #[test]
    fn corrupt_files_are_refused_without_panicking() {
        let scene = scene();
        let solved = solve(&scene, DomainMode::Extended, 2, Quantity::Radiance);
        let bytes = encoded(&solved, DomainMode::Extended);
        let refuse = |b: &[u8]| decode_for(b, &scene).expect_err("refused");
        assert!(matches!(refuse(&[]), SolutionFileError::BadMagic));
        let mut wrong_magic = bytes.clone();
        wrong_magic[0] = b'X';
        assert!(matches!(refuse(&wrong_magic), SolutionFileError::BadMagic));
        let mut wrong_version = bytes.clone();
        wrong_version[8..12].copy_from_slice(&2u32.to_le_bytes());
        assert!(matches!(
            refuse(&wrong_version),
            SolutionFileError::Version { found: 2 }
        ));
        // Truncated anywhere, one byte flipped anywhere: refused.
        let step = (bytes.len() / 97).max(1);
        for cut in (0..bytes.len()).step_by(step) {
            refuse(&bytes[..cut]);
        }
        for at in (12..bytes.len()).step_by(step) {
            let mut b = bytes.clone();
            b[at] ^= 0x10;
            assert!(matches!(refuse(&b), SolutionFileError::Corrupt(_)), "{at}");
        }
        // Consistent checksum but nonsense content (counts, a child out of bounds): refused.
        let reseal = |mut b: Vec<u8>| {
            let n = b.len() - 8;
            let mut h = Fnv::new();
            h.update(&b[..n]);
            b[n..].copy_from_slice(&h.0.to_le_bytes());
            b
        };
        let mut huge_count = bytes.clone();
        huge_count[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(
            refuse(&reseal(huge_count)),
            SolutionFileError::Corrupt(_)
        ));
        // Root 0's first node: header 32 bytes, root header 13, then the map (48) and depth (1).
        let mut bad_child = bytes.clone();
        bad_child[32 + 13 + 49..32 + 13 + 53].copy_from_slice(&7u32.to_le_bytes());
        assert!(matches!(
            refuse(&reseal(bad_child)),
            SolutionFileError::Corrupt(_)
        ));
        // Another scene (the triangle moved): its roots do not match.
        let mut b = SceneBuilder::new();
        let m = b.material([0.5; 3], [1.0; 3], false);
        b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
        let other = load_scene(&b.to_glb(), &ExternalFiles::Refuse, 10).unwrap();
        let e = decode_for(&bytes, &other).expect_err("another scene");
        assert!(matches!(e, SolutionFileError::Mismatch(_)), "{e}");
        // A missing file says so.
        let e = read(Path::new("/nonexistent/solution.bin")).expect_err("missing");
        assert!(e.is_missing());
    }

    #[test]
    fn prepare_is_deterministic() {
        let scene = scene();
        for mode in [DomainMode::Extended, DomainMode::Tessellated] {
            let a = roots_fingerprint(&prepare(&scene, mode).roots);
            let b = roots_fingerprint(&prepare(&scene, mode).roots);
            assert_eq!(a, b);
        }
    }

    #[test]
    fn save_is_atomic_and_loads_back() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("target/tmp-solution-file-unit");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let scene = scene();
        let solved = solve(&scene, DomainMode::Extended, 1, Quantity::Radiance);
        let path = dir.join(SOLUTION_FILE);
        save(&path, &solved, DomainMode::Extended).unwrap();
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from(SOLUTION_FILE)]);
        assert_eq!(
            std::fs::read(&path).unwrap(),
            encoded(&solved, DomainMode::Extended)
        );
        decode_for(&std::fs::read(&path).unwrap(), &scene).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
    }
}
