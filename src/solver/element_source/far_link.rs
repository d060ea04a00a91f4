//! The one-ray path of an [`ElementSource`]: a far link's irradiance (`far_irradiance_at`: one
//! shadow ray to the source's centre stands for every rule point's, its verdict kept for the pair
//! in the shooter's table when there is one; beyond the rule's radii the rule's sums in one pass,
//! `rule_sums`, on a partly covered element too), and the centre ray itself (`centre_verdict`,
//! which a [`Rays::Centre`](super::Rays::Centre) link's points use as well) with the point it
//! ends at (`centre_stand_in`, on the face).
//!
//! Invariant: with every point seen, `rule_sums` is `rule_form_factor` and `with_verdicts` bit for
//! bit (`tests::the_rule_sums_are_with_verdicts_all_seen`), so a far link beyond the rule's radii
//! delivers what the rule-point path would with all its rays passing.

use super::ElementSource;
use crate::scene::Rgb;
use crate::solver::element::visibility_point;
use crate::solver::far_verdicts::VerdictTable;
use glam::{DVec2, DVec3};

impl ElementSource<'_> {
    /// The irradiance of a far link at `x` (normal `n`): [`Source::irradiance_at`] with one
    /// shadow ray, to the source's centre, standing for every rule point's (0 when it is
    /// blocked), and beyond the rule's radii ([`Emitter::far_in_front`]) the rule's sum for the
    /// form factor even on a partly covered element (its coverage-weighted rule is a few percent
    /// off the face's exact form factor there). A far link's whole transfer is within the
    /// oracle's threshold (`far_field.rs`), the budget any other estimate of it would be
    /// allowed. `None` when `x` is behind the source or the source's plane. `verdict`: the
    /// shooter's table of far links' verdicts and the receiver's index in it, which keeps the
    /// ray's verdict for the pair (`far_verdicts.rs`); a pair it knows blocked gets nothing at
    /// once, its form factor not evaluated (it was positive when the ray was traced, and
    /// depends on the pair alone: `a_far_link_reads_its_verdict_back_from_the_shooters_table`).
    ///
    /// [`Source::irradiance_at`]: super::Source::irradiance_at
    /// [`Emitter::far_in_front`]: super::Emitter::far_in_front
    pub(in crate::solver) fn far_irradiance_at(
        &self,
        x: DVec3,
        n: DVec3,
        ignore: [u32; 2],
        verdict: Option<(&VerdictTable, usize)>,
    ) -> Option<Rgb> {
        // A pair known blocked: an earlier shot traced it, having found the form factor
        // positive (it depends on the pair alone), and nothing reaches the receiver.
        if verdict.is_some_and(|(table, r)| table.known(r) == Some(false)) {
            return Some([0.0; 3]);
        }
        // Beyond the rule's radii, the rule's sums: its form factor and what it delivers seen
        // whole (what `with_verdicts` gives with every point seen, its rescaling exactly 1).
        let (f, rule_e) = if self
            .emitter
            .far_in_front(x, n, self.shot.rules.form_factor_radii)
        {
            let (f, e) = self.rule_sums(x, n);
            (f, Some(e))
        } else {
            (self.form_factor(x, n), None)
        };
        if f <= 0.0 {
            return None;
        }
        let trace = || self.centre_verdict(x, ignore) != 0;
        let seen = match verdict {
            Some((table, r)) => table.visible(r, trace),
            None => trace(),
        };
        if !seen {
            // What `with_verdicts` gives with no point seen.
            return Some([0.0; 3]);
        }
        Some(rule_e.unwrap_or_else(|| self.with_verdicts(x, n, f, u64::MAX, None).e))
    }

    /// The verdicts of every rule point from `x` as one shadow ray to the source's centre
    /// decides them: all seen (`u64::MAX`) or none (0, without a ray when no rule point emits).
    pub(super) fn centre_verdict(&self, x: DVec3, ignore: [u32; 2]) -> u64 {
        if self.alpha_weight <= 0.0 {
            return 0;
        }
        let centre = *self.centre_stand_in.get_or_init(|| self.centre_stand_in());
        super::trace_packet(self.shot.visibility, x, &[centre], ignore)
    }

    /// The emitting rule points' weighted mean, on the face: the mean itself when the face
    /// covers it, else its closest point on the face (off an L-shaped face or in a hole, the
    /// mean would send a far link's ray to a point that may lie inside another object).
    fn centre_stand_in(&self) -> DVec3 {
        let st = self
            .rule
            .iter()
            .zip(&self.alpha)
            .map(|(q, &a)| q.st * (q.weight * a))
            .sum::<DVec2>()
            / self.alpha_weight;
        visibility_point(self.root, &self.src.map, st)
    }

    /// The rule's form factor at `x` (normal `n`, as [`ElementSource::rule_form_factor`]) and
    /// the irradiance its emitting points deliver there all seen: the terms and the order of
    /// [`ElementSource::with_verdicts`], whose result with every point seen and `f` this form
    /// factor it is bit for bit (`tests::the_rule_sums_are_with_verdicts_all_seen`), in one pass
    /// over the points.
    pub(super) fn rule_sums(&self, x: DVec3, n: DVec3) -> (f64, Rgb) {
        let (mut f, mut e) = (0.0, [0.0; 3]);
        for (l, kxy) in self.front_terms(x, n) {
            f += kxy;
            for ch in 0..3 {
                e[ch] += kxy * self.radiosity[l][ch];
            }
        }
        (f, e)
    }
}
