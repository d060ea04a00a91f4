//! `ElementSource` pinned against independent values: a far link's form factor on a partly
//! covered source, a far link's one-pass rule sums against `with_verdicts`, and a source cut by
//! the receiver's plane under an eave against a fine grid of the source with the eave decided
//! exactly.

use super::*;
use crate::domain::Shape;
use crate::solver::basis::Basis;
use crate::solver::element::tests::parallelogram_root;

/// A shot of `roots[0]` (direct or not), with no stored face means and a 1 mm smallest edge.
pub(in crate::solver) fn shot_of_first_root<'a>(
    roots: &'a [ElementRoot],
    (bases, rules): (&'a Bases, &'a Rules),
    visibility: &'a Visibility,
    hierarchy: &'a Hierarchy,
    direct: bool,
) -> ElementShot<'a> {
    ElementShot {
        roots,
        bases,
        rules,
        visibility,
        source_root: 0,
        source_hierarchy: hierarchy,
        direct,
        source_face_means: None,
        min_edge: 1e-3,
    }
}

/// The unit square in the plane z = 0 with a centred hole of half its side (face area 0.75),
/// shooting as one partly covered element: the root and its element's cover.
fn holed_unit_square(rules: &Rules, basis: &Basis) -> (ElementRoot, NodeCover) {
    let mut root = parallelogram_root(DVec3::ZERO, DVec3::X, DVec3::Y);
    let mask = crate::solver::cover::tests::holed(0.5);
    let cover = NodeCover::new(&mask, &ChildMap::IDENTITY, &rules.cover, basis, true);
    assert_eq!(cover.status, ElementStatus::Partial);
    root.mask = Some(mask);
    root.face_area_m2 = 0.75;
    (root, cover)
}

/// A far link on a partly covered source (a unit square with a centred hole of half its side,
/// shooting as one element with its face's rings) takes the rule's sum for the form factor
/// beyond the rule's radii, where a near link takes the exact contour integral of the rings:
/// the far link's irradiance over the near link's is the rule's sum over the exact form
/// factor, which differ there. Nearer than the radii both take the exact one.
#[test]
fn a_far_link_on_a_partly_covered_source_takes_the_rule_beyond_its_radii() {
    let order = 2;
    let (bases, rules) = (Bases::new(order), Rules::new(order));
    let basis = Basis::new(Shape::Parallelogram, order);
    let n = basis.len();
    let (mut source, cover) = holed_unit_square(&rules, &basis);
    source.exitance = [1.0; 3];
    let roots = [source];
    let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
    coeffs[0] = roots[0].exitance;
    let element = SourceElement::root(&roots[0], coeffs, n, Some(cover), None);
    assert!(
        element.rings.is_some(),
        "a partly covered element has rings"
    );
    let hierarchy = Hierarchy::new(n);
    let visibility = Visibility::new(Vec::new(), 30.0);
    let shot = shot_of_first_root(&roots, (&bases, &rules), &visibility, &hierarchy, true);
    let source = shot.source(&element, [1.0; 3]).expect("an emitting source");
    let ignore = source.ignored_faces(1);
    let (down, radii) = (-DVec3::Z, rules.form_factor_radii);
    let radius = 0.5f64.sqrt();
    // Off the centre's axis, so that the hole does not sit symmetrically under the point.
    let above = |z: f64| DVec3::new(0.8, 0.3, z);
    let ratio = |x: DVec3| {
        let far = source
            .far_irradiance_at(x, down, ignore, None)
            .expect("in front");
        let near = source
            .irradiance_at(x, down, ignore, Rays::Trace, None)
            .expect("in front")
            .e;
        far[0] / near[0]
    };
    let x = above(radii * radius * 1.05);
    let (rule, exact) = (
        source.rule_form_factor(x, down),
        source.form_factor(x, down),
    );
    assert!(
        (rule / exact - 1.0).abs() > 1e-4,
        "the rule {rule} and the rings {exact} must differ for the check to mean anything"
    );
    let r = ratio(x);
    assert!(
        (r - rule / exact).abs() < 1e-12,
        "{r} against {}",
        rule / exact
    );
    // Nearer than the radii, the far link takes the rings' exact form factor too.
    let r = ratio(above(radii * radius * 0.9));
    assert!((r - 1.0).abs() < 1e-12, "{r}");
}

/// Random sources seen from random points, for the bit-for-bit checks below: `count` random
/// radiosities (every basis function) on a whole unit square, then on a holed, partly covered
/// one, each seen from a random point within 10 units of the square's centre on each axis (in
/// front of it or not) with a random normal. `check` gets whether the source is holed, the source, the point,
/// the normal and the random sequence.
fn for_random_sources_and_points(
    seed: u64,
    count: usize,
    mut check: impl FnMut(bool, &ElementSource, DVec3, DVec3, &mut dyn FnMut() -> f64),
) {
    let order = 2;
    let (bases, rules) = (Bases::new(order), Rules::new(order));
    let basis = Basis::new(Shape::Parallelogram, order);
    let n = basis.len();
    let mut rnd = crate::shuffle::uniform_sequence(seed);
    let visibility = Visibility::new(Vec::new(), 30.0);
    let hierarchy = Hierarchy::new(n);
    for holed in [false, true] {
        let (root, cover) = if holed {
            let (root, cover) = holed_unit_square(&rules, &basis);
            (root, Some(cover))
        } else {
            (parallelogram_root(DVec3::ZERO, DVec3::X, DVec3::Y), None)
        };
        let roots = [root];
        for _ in 0..count {
            let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
            for c in coeffs.iter_mut().take(n) {
                *c = [rnd() - 0.3, rnd(), 2.0 * rnd() - 1.0];
            }
            let element = SourceElement::root(&roots[0], coeffs, n, cover, None);
            let shot = shot_of_first_root(&roots, (&bases, &rules), &visibility, &hierarchy, false);
            let Some(source) = shot.source(&element, [1.0; 3]) else {
                continue;
            };
            let mut v = || DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
            let x = DVec3::new(0.5, 0.5, 0.0) + v() * 20.0;
            let normal = v().normalize();
            check(holed, &source, x, normal, &mut rnd);
        }
    }
}

/// `rule_sums` is `rule_form_factor` and `with_verdicts` with every point seen, bit for bit, on
/// [`for_random_sources_and_points`].
#[test]
fn the_rule_sums_are_with_verdicts_all_seen() {
    let mut checked = 0;
    for_random_sources_and_points(5, 200, |_, source, x, normal, _| {
        let (f, e) = source.rule_sums(x, normal);
        assert_eq!(f, source.rule_form_factor(x, normal));
        if f > 0.0 {
            assert_eq!(e, source.with_verdicts(x, normal, f, u64::MAX, None).e);
            checked += 1;
        } else {
            assert_eq!(e, [0.0; 3]);
        }
    });
    assert!(checked > 100, "{checked} points received light");
}

/// The eave of the two tests below: the plane y = 0 from x = -0.3 (over the building) to 0.05
/// (out from the wall x = 0), 4 m long.
const EAVE_X: std::ops::RangeInclusive<f64> = -0.3..=0.05;

fn eave() -> Visibility {
    let (x0, x1) = (*EAVE_X.start(), *EAVE_X.end());
    let (a, b) = (DVec3::new(x0, 0.0, -2.0), DVec3::new(x1, 0.0, -2.0));
    let (c, d) = (DVec3::new(x1, 0.0, 2.0), DVec3::new(x0, 0.0, 2.0));
    Visibility::new([([a, b, c], 7), ([a, c, d], 7)], 10.0)
}

/// The receiving point of the two tests below: on the wall x = 0, 2 cm under the eave.
const UNDER_THE_EAVE: DVec3 = DVec3::new(1e-4, -0.02, 0.1);

/// The irradiance at [`UNDER_THE_EAVE`] (facing +x) from the parallelogram `root` (its frame
/// the source) of radiosity `radiosity(st)`, on a 600 x 600 midpoint grid with the eave decided
/// exactly: what passes the eave, and everything in front of the wall.
fn fine_grid(root: &ElementRoot, radiosity: impl Fn(DVec2) -> f64) -> (f64, f64) {
    let (x, normal, f) = (UNDER_THE_EAVE, DVec3::X, &root.frame);
    let grid = 600;
    let cell = f.u.cross(f.v).length() / (grid * grid) as f64;
    let (mut passing, mut unoccluded) = (0.0, 0.0);
    for st in quadrature::unit_square_midpoints(grid) {
        let y = f.point(st);
        let k = kernel::geometric_kernel(x, normal, y, root.normal) * cell * radiosity(st);
        // Where the segment crosses the eave's plane y = 0.
        let crossing = x + (y - x) * ((0.0 - x.y) / (y.y - x.y));
        unoccluded += k;
        if !EAVE_X.contains(&crossing.x) {
            passing += k;
        }
    }
    (passing, unoccluded)
}

/// A sky over a wall with an eave: from a point on the wall 2 cm under a 5 cm eave, a large
/// emitter cut by the wall's plane is seen only far out, past the eave's edge. With M1's
/// four points the front part is sampled as a whole (the rule carried onto it), not by the
/// one column of points that happens to lie in front of the wall, which all see past the
/// eave and gave the unshadowed wall's light (the Kenney building's eaves at M1,
/// docs/accuracy-history.md). Against the same irradiance from a fine grid over the source.
#[test]
fn a_source_cut_by_the_receivers_plane_is_sampled_in_front_of_it() {
    let order = 1;
    let (bases, rules) = (Bases::new(order), Rules::new(order));
    let n = Basis::new(Shape::Parallelogram, order).len();
    // The sky: 3 m x 3 m at y = 0.2, facing down; the wall's plane x = 0 cuts it in two.
    let mut sky = parallelogram_root(
        DVec3::new(-1.5, 0.2, -1.5),
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(0.0, 0.0, 3.0),
    );
    assert!(sky.normal.y < -0.99);
    sky.exitance = [1.0; 3];
    let roots = [sky];
    let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
    coeffs[0] = roots[0].exitance;
    let element = SourceElement::root(&roots[0], coeffs, n, None, None);
    let visibility = eave();
    let hierarchy = Hierarchy::new(n);
    let shot = shot_of_first_root(&roots, (&bases, &rules), &visibility, &hierarchy, true);
    let source = shot.source(&element, [1.0; 3]).expect("an emitting source");
    let got = source
        .irradiance_at(
            UNDER_THE_EAVE,
            DVec3::X,
            source.ignored_faces(1),
            Rays::Trace,
            None,
        )
        .expect("in front")
        .e[0];
    let (exact, unoccluded) = fine_grid(&roots[0], |_| 1.0);
    assert!(
        exact < 0.5 * unoccluded,
        "the eave must hide most of the sky: {exact} of {unoccluded}"
    );
    // Four samples of a front part the eave's shadow crosses: within half the exact value,
    // where the column of rule points in front (all seen past the eave) gave the unoccluded
    // value, four times it.
    assert!(
        (got - exact).abs() < 0.5 * exact,
        "{got} against {exact} (unoccluded {unoccluded})"
    );
}

/// The same under a sky turned 30 degrees about the vertical (the wall's plane cuts it
/// diagonally, the map's Jacobian varies) that shoots a radiosity varying across it (M2's
/// linear functions): the front rule's nine rays, mixed verdicts, and the irradiance within a
/// quarter of the fine grid's, where the rule points in front gave 3.7 times it.
#[test]
fn a_varying_source_cut_diagonally_is_sampled_in_front_of_the_plane() {
    let order = 2;
    let (bases, rules) = (Bases::new(order), Rules::new(order));
    let basis = Basis::new(Shape::Parallelogram, order);
    let n = basis.len();
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let (u, v) = (
        DVec3::new(3.0 * c, 0.0, -3.0 * s),
        DVec3::new(3.0 * s, 0.0, 3.0 * c),
    );
    let sky = parallelogram_root(DVec3::new(0.0, 0.2, 0.0) - 0.5 * (u + v), u, v);
    assert!(sky.normal.y < -0.99);
    let roots = [sky];
    let mut coeffs = [[0.0; 3]; MAX_FUNCTIONS];
    coeffs[0] = [1.0; 3];
    coeffs[1] = [0.3; 3];
    coeffs[2] = [-0.2; 3];
    let element = SourceElement::root(&roots[0], coeffs, n, None, None);
    let visibility = eave();
    let hierarchy = Hierarchy::new(n);
    let shot = shot_of_first_root(&roots, (&bases, &rules), &visibility, &hierarchy, false);
    let source = shot.source(&element, [1.0; 3]).expect("an emitting source");
    let under_the_eave = |known| {
        let ignore = source.ignored_faces(1);
        source
            .irradiance_at(UNDER_THE_EAVE, DVec3::X, ignore, Rays::Trace, known)
            .expect("in front")
    };
    let rays_before = visibility.rays_traced();
    let got = under_the_eave(None);
    assert_eq!(
        visibility.rays_traced() - rays_before,
        rules.of(Shape::Parallelogram).len() as u64
    );
    assert!(
        got.any_visible && got.any_blocked,
        "the eave's shadow crosses the front part"
    );
    // What the rays said, read back by a later shot (`near_verdicts.rs`): the same light, and no
    // ray traced.
    let before = visibility.rays_traced();
    let again = under_the_eave(Some(KnownPoint {
        seen: got.seen,
        form_factor: got.form_factor,
    }));
    assert_eq!(visibility.rays_traced(), before);
    assert_eq!(
        (again.e, again.any_visible, again.any_blocked, again.seen),
        (got.e, got.any_visible, got.any_blocked, got.seen)
    );
    assert_eq!(
        (again.form_factor, again.unoccluded, again.source_side_err),
        (got.form_factor, got.unoccluded, got.source_side_err)
    );
    let (exact, unoccluded) = fine_grid(&roots[0], |st| {
        let mut phi = [0.0; MAX_FUNCTIONS];
        basis.eval(st, &mut phi[..n]);
        (0..n).map(|k| phi[k] * coeffs[k][0]).sum()
    });
    assert!(exact < 0.5 * unoccluded, "{exact} of {unoccluded}");
    assert!(
        (got.e[0] - exact).abs() < 0.25 * exact,
        "{} against {exact} (unoccluded {unoccluded})",
        got.e[0]
    );
}

/// Where the form factor is the rule's sum, the terms it summed give `with_verdicts` what it
/// computes on its own, bit for bit, whatever the verdicts, on [`for_random_sources_and_points`]
/// with random verdicts (the holed source's form factor is always the contour integral's: no
/// terms).
#[test]
fn the_form_factors_terms_give_with_verdicts_its_own() {
    let mut with_terms = 0;
    for_random_sources_and_points(11, 400, |holed, source, x, normal, rnd| {
        let (f, terms) = source.form_factor_and_terms(x, normal);
        let Some(terms) = terms else { return };
        assert!(
            !holed,
            "a partly covered source's form factor is the contour integral's"
        );
        assert_eq!(f.to_bits(), source.rule_form_factor(x, normal).to_bits());
        if f <= 0.0 {
            return;
        }
        let seen = (rnd() * 512.0) as u64;
        assert_eq!(
            format!(
                "{:?}",
                source.with_verdicts(x, normal, f, seen, Some(&terms))
            ),
            format!("{:?}", source.with_verdicts(x, normal, f, seen, None)),
        );
        with_terms += 1;
    });
    assert!(with_terms > 50, "{with_terms} points took the rule's terms");
}
