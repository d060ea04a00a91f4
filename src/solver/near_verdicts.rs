//! The shadow-ray verdicts of near links, kept from one indirect shot of a root to the next.
//!
//! A root shoots again and again as light comes back to it, and its near links to a receiver
//! are evaluated, shot after shot, between the same parts: the same element of the shooter (its
//! path of splits from the root, [`SourcePath`]) and the same node of the receiver (nodes are
//! only ever added). What such a link's rays say depends on geometry alone: the receiver node's
//! points, the source element's emitting rule points (or its centre; or, where a point's tangent
//! plane cuts the element, its rule carried onto the part in front, `front_map.rs`), the two
//! faces the rays ignore; and so does whether the oracle's verdict rays (corners, then spread pairs) disagree
//! with the quadrature's, and each point's form factor of the source element (exact, a contour
//! integral over its rings, or the rule's sum). Each receiver root keeps, in its hierarchy, one
//! entry per such link ([`LinkKey`]: shooter root, source path, receiver node, one ray per
//! point or a packet): per receiver point its form factor and its ray mask, and the verdict
//! rays' answer once the oracle asked for it. A later shot reads them instead of computing and
//! tracing them.
//!
//! Invariants: a verdict or form factor read is the one the rays or the integral would give
//! (the solve is the same with or without the entries: `tests/solver.rs`
//! `near_link_verdicts_kept_between_shots_change_no_light_and_save_rays`); the entries of all
//! receivers take about at most the budget (`SolverParams::near_verdict_bytes`): a table
//! reserves its grown size from the shared [`VerdictBudget`] before it grows, and links it has
//! no room for trace as before (which links those are then depends on the threads' timing: the
//! light does not, the ray count may). An entry is written by the thread that holds the
//! receiver's hierarchy, never changed but for the verdict rays' answer, which it gains once.

use super::cover::MAX_POINTS;
use super::shot_record::SourcePath;
use super::source::KnownPoint;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A near link between two parts, as its rays see it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) struct LinkKey {
    shooter: u32,
    path: SourcePath,
    node: u32,
    /// One ray per receiver point, to the source's centre (`Rays::Centre`), not a packet.
    centre: bool,
}

impl LinkKey {
    pub fn new(shooter: usize, path: SourcePath, node: usize, centre: bool) -> Self {
        LinkKey {
            shooter: shooter as u32,
            path,
            node: node as u32,
            centre,
        }
    }
}

/// What a link's points saw: from `values[start..]`, each point's form factor (its bits), then,
/// when some point's rays disagree among themselves (`mixed`), each point's mask; otherwise
/// bit `k` of `visible` says whether every ray of point `k` passed.
#[derive(Debug, Clone, Copy)]
struct Entry {
    visible: u64,
    start: u32,
    points: u8,
    mixed: bool,
    /// The oracle's verdict rays: 0 not asked yet, 1 they agree, 2 they disagree.
    verdict_rays: u8,
}

/// A point's mask when every one of its rays passed (bits past its rays are never read).
pub(super) const ALL_VISIBLE: u64 = u64::MAX;

/// Bytes a table entry takes, with the hash table's control byte.
const ENTRY_BYTES: usize = std::mem::size_of::<(LinkKey, Entry)>() + 1;

/// Bytes of a table holding `entries` entries and `values` form factors and masks without
/// growing: the hash table's buckets are about 8/7 of what it holds.
fn table_bytes(entries: usize, values: usize) -> usize {
    entries * ENTRY_BYTES * 8 / 7 + values * std::mem::size_of::<u64>()
}

/// The capacity a `Vec<u64>` of `capacity` has once it holds `needed` values, grown by one
/// `reserve` as std grows it (double, or what is needed when more, at least 4).
fn grown_capacity(capacity: usize, needed: usize) -> usize {
    if needed > capacity {
        (2 * capacity).max(needed).max(4)
    } else {
        capacity
    }
}

/// One receiver root's kept verdicts.
#[derive(Debug, Clone, Default)]
pub struct NearVerdicts {
    entries: HashMap<LinkKey, Entry>,
    values: Vec<u64>,
}

/// A link's kept verdicts, read back.
#[derive(Debug, Clone, Copy)]
pub(super) struct KnownVerdicts<'a> {
    entry: Entry,
    values: &'a [u64],
}

impl KnownVerdicts<'_> {
    /// What point `k` saw: its ray mask (packing order of its rays, [`ALL_VISIBLE`] when all
    /// passed) and its form factor (0 where nothing reached it).
    pub fn point(&self, k: usize) -> KnownPoint {
        let (start, points) = (self.entry.start as usize, usize::from(self.entry.points));
        debug_assert!(k < points, "a point of the link");
        let seen = if self.entry.mixed {
            self.values[start + points + k]
        } else if self.entry.visible >> k & 1 == 1 {
            ALL_VISIBLE
        } else {
            0
        };
        KnownPoint {
            seen,
            form_factor: f64::from_bits(self.values[start + k]),
        }
    }

    /// Whether the oracle's verdict rays disagree with the quadrature, once a shot asked.
    pub fn verdict_rays(&self) -> Option<bool> {
        match self.entry.verdict_rays {
            0 => None,
            v => Some(v == 2),
        }
    }
}

/// The bytes every receiver's tables may take together.
#[derive(Debug)]
pub(super) struct VerdictBudget {
    used: AtomicUsize,
    limit: usize,
}

impl VerdictBudget {
    pub fn new(limit: usize) -> Self {
        VerdictBudget {
            used: AtomicUsize::new(0),
            limit,
        }
    }

    /// Bytes the tables take.
    pub fn used(&self) -> usize {
        self.used.load(Ordering::Relaxed)
    }

    /// Takes `bytes` from the budget if they fit.
    fn reserve(&self, bytes: usize) -> bool {
        self.used
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |u| {
                u.checked_add(bytes).filter(|&total| total <= self.limit)
            })
            .is_ok()
    }

    /// Sets what a reservation of `reserved` bytes turned out to take: `actual`.
    fn settle(&self, reserved: usize, actual: usize) {
        if actual >= reserved {
            self.used.fetch_add(actual - reserved, Ordering::Relaxed);
        } else {
            self.used.fetch_sub(reserved - actual, Ordering::Relaxed);
        }
    }
}

impl NearVerdicts {
    /// The link's kept verdicts, if a shot kept them.
    pub(super) fn known(&self, key: &LinkKey) -> Option<KnownVerdicts<'_>> {
        self.entries.get(key).map(|&entry| KnownVerdicts {
            entry,
            values: &self.values,
        })
    }

    /// Keeps what a link's points saw (`seen`: each point's mask, `ALL_VISIBLE` for a point all
    /// of whose rays passed; `form_factors`: each point's, 0 where nothing reached it;
    /// `verdict_rays`: the oracle's answer, if it asked), within `budget`: a new entry, or the
    /// verdict rays' answer for a kept one that lacked it.
    pub(super) fn keep(
        &mut self,
        key: LinkKey,
        (seen, form_factors): (&[u64], &[f64]),
        verdict_rays: Option<bool>,
        budget: &VerdictBudget,
    ) {
        debug_assert!(seen.len() <= MAX_POINTS.min(64) && form_factors.len() == seen.len());
        let answer = verdict_rays.map_or(0, |d| 1 + u8::from(d));
        if let Some(entry) = self.entries.get_mut(&key) {
            if entry.verdict_rays == 0 {
                entry.verdict_rays = answer;
            }
            return;
        }
        let uniform = seen.iter().all(|&m| m == 0 || m == ALL_VISIBLE);
        let before = self.bytes();
        // What the table will take once the entry is in (the hash table and the masks grow as
        // their std implementations do: about double), reserved before it grows.
        let (len, capacity) = (self.entries.len(), self.entries.capacity());
        let entries_after = if len == capacity {
            (2 * capacity + 1).max(3)
        } else {
            capacity
        };
        let values_needed = self.values.len() + seen.len() * if uniform { 1 } else { 2 };
        let values_after = grown_capacity(self.values.capacity(), values_needed);
        let reserved = table_bytes(entries_after, values_after).saturating_sub(before);
        // An offset past `u32` is not kept (some 32 GiB of one receiver's values).
        let Ok(start) = u32::try_from(self.values.len()) else {
            return;
        };
        if !budget.reserve(reserved) {
            return;
        }
        // One growth at most, as reserved.
        self.values.reserve(values_needed - self.values.len());
        self.values.extend(form_factors.iter().map(|f| f.to_bits()));
        if !uniform {
            self.values.extend_from_slice(seen);
        }
        let visible = seen
            .iter()
            .enumerate()
            .fold(0u64, |v, (k, &m)| v | u64::from(m == ALL_VISIBLE) << k);
        self.entries.insert(
            key,
            Entry {
                visible,
                start,
                points: seen.len() as u8,
                mixed: !uniform,
                verdict_rays: answer,
            },
        );
        budget.settle(reserved, self.bytes().saturating_sub(before));
    }

    /// Bytes the table takes (about: the hash table's buckets, its control bytes, the values).
    pub fn bytes(&self) -> usize {
        table_bytes(self.entries.capacity(), self.values.capacity())
    }

    /// Frees the table (the solve is over: no shot reads it again).
    pub fn clear(&mut self) {
        *self = NearVerdicts::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(node: usize) -> LinkKey {
        LinkKey::new(3, SourcePath::ROOT.child(2), node, false)
    }

    /// Uniform and mixed masks and the form factors read back as kept, per point; the verdict
    /// rays' answer is kept once and never changed; other links are unknown.
    #[test]
    fn verdicts_read_back_as_kept() {
        let budget = VerdictBudget::new(usize::MAX);
        let mut t = NearVerdicts::default();
        let uniform = [ALL_VISIBLE, 0, ALL_VISIBLE, ALL_VISIBLE];
        let mixed = [0b1011, ALL_VISIBLE, 0, 0b1];
        let (fa, fb) = ([0.25, 0.0, 1e-300, 0.5], [0.125, 0.3, 0.0, 0.7]);
        t.keep(key(1), (&uniform, &fa), None, &budget);
        t.keep(key(2), (&mixed, &fb), Some(true), &budget);
        let a = t.known(&key(1)).expect("kept");
        let b = t.known(&key(2)).expect("kept");
        for k in 0..4 {
            assert_eq!(a.point(k).seen, uniform[k], "point {k}");
            assert_eq!(b.point(k).seen, mixed[k], "point {k}");
            assert_eq!(a.point(k).form_factor, fa[k], "point {k}");
            assert_eq!(b.point(k).form_factor, fb[k], "point {k}");
        }
        assert_eq!(a.verdict_rays(), None);
        assert_eq!(b.verdict_rays(), Some(true));
        t.keep(key(1), (&[0; 4], &[0.0; 4]), Some(false), &budget);
        t.keep(key(2), (&[0; 4], &[0.0; 4]), Some(false), &budget);
        let a = t.known(&key(1)).expect("kept");
        assert_eq!(a.point(0).seen, ALL_VISIBLE, "masks are never changed");
        assert_eq!(a.point(0).form_factor, 0.25, "nor form factors");
        assert_eq!(a.verdict_rays(), Some(false), "gained once");
        assert_eq!(t.known(&key(2)).expect("kept").verdict_rays(), Some(true));
        assert!(t.known(&key(3)).is_none());
        assert!(t
            .known(&LinkKey::new(3, SourcePath::ROOT.child(2), 1, true))
            .is_none());
        assert!(t
            .known(&LinkKey::new(4, SourcePath::ROOT.child(2), 1, false))
            .is_none());
        assert!(t
            .known(&LinkKey::new(3, SourcePath::ROOT, 1, false))
            .is_none());
        assert_eq!(budget.used(), t.bytes());
    }

    /// Tables grow only while the budget holds their grown size (uniform and mixed entries,
    /// of several sizes), the values once per entry at most, to what was reserved; a full
    /// budget keeps nothing new, and what was kept stays readable.
    #[test]
    fn tables_stay_within_the_budget() {
        let limit = table_bytes(64, 64);
        let budget = VerdictBudget::new(limit);
        let mut tables = [NearVerdicts::default(), NearVerdicts::default()];
        for node in 0..1000 {
            let t = &mut tables[node % 2];
            let points = 1 + node % 13;
            let mask = if node % 3 == 0 { ALL_VISIBLE } else { 0b10 };
            let (seen, ff) = ([mask; 13], [0.5; 13]);
            let capacity = t.values.capacity();
            t.keep(key(node), (&seen[..points], &ff[..points]), None, &budget);
            assert!(budget.used() <= limit, "{} of {limit}", budget.used());
            // The values grew once at most, to the size `keep` reserved (none when they fit).
            assert_eq!(
                t.values.capacity(),
                grown_capacity(capacity, t.values.len()),
                "node {node}: {capacity} -> {} values",
                t.values.capacity()
            );
        }
        let kept: usize = (0..1000)
            .filter(|&n| tables[n % 2].known(&key(n)).is_some())
            .count();
        assert!(kept > 0 && kept < 1000, "{kept} kept");
        let bytes: usize = tables.iter().map(NearVerdicts::bytes).sum();
        assert_eq!(budget.used(), bytes);
        assert!(bytes <= limit, "{bytes} bytes of {limit}");
        let none = VerdictBudget::new(0);
        let mut t = NearVerdicts::default();
        t.keep(key(0), (&[0; 4], &[0.0; 4]), None, &none);
        assert!(t.known(&key(0)).is_none());
    }
}
