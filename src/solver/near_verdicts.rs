//! The shadow-ray verdicts of near links, kept from one indirect shot of a root to the next.
//!
//! A root shoots again and again as light comes back to it, and its near links to a receiver
//! are evaluated, shot after shot, between the same parts: the same element of the shooter (its
//! path of splits from the root, [`SourcePath`]) and the same node of the receiver (nodes are
//! only ever added). What such a link's rays say depends on geometry alone: the receiver node's
//! points, the source element's emitting rule points (or its centre; or, where a point's tangent
//! plane cuts the element, its rule carried onto the part in front, `front_map.rs`), the two
//! faces the rays ignore; and so does whether the oracle's verdict rays (corners, then spread pairs) disagree
//! with the quadrature's. Each receiver root keeps, in its hierarchy, one entry per such link
//! ([`LinkKey`]: shooter root, source path, receiver node, one ray per point or a packet):
//! per receiver point its ray mask, and the verdict rays' answer once the oracle asked for it.
//! A later shot reads them instead of tracing.
//!
//! Invariants: a verdict read is the one the rays would give (the solve is the same with or
//! without the entries: `tests/solver.rs`
//! `near_link_verdicts_kept_between_shots_change_no_light_and_save_rays`); the entries of all
//! receivers take about at most the budget (`SolverParams::near_verdict_bytes`): a table
//! reserves its grown size from the shared [`VerdictBudget`] before it grows, and links it has
//! no room for trace as before (which links those are then depends on the threads' timing: the
//! light does not, the ray count may). An entry is written by the thread that holds the
//! receiver's hierarchy, never changed but for the verdict rays' answer, which it gains once.

use super::shot_record::SourcePath;
use super::transfer::MAX_POINTS;
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

/// What a link's rays said: per point, bit `k` of `visible` when every ray of point `k` passed;
/// the masks of every point in `masks[mixed..]` when some point's rays disagree among
/// themselves (`NO_MASKS` otherwise: each point's rays all passed, or all stopped).
#[derive(Debug, Clone, Copy)]
struct Entry {
    visible: u64,
    mixed: u32,
    points: u8,
    /// The oracle's verdict rays: 0 not asked yet, 1 they agree, 2 they disagree.
    verdict_rays: u8,
}

const NO_MASKS: u32 = u32::MAX;

/// A point's mask when every one of its rays passed (bits past its rays are never read).
pub(super) const ALL_VISIBLE: u64 = u64::MAX;

/// Bytes a table entry takes, with the hash table's control byte.
const ENTRY_BYTES: usize = std::mem::size_of::<(LinkKey, Entry)>() + 1;

/// Bytes of a table holding `entries` entries and `masks` masks without growing: the hash
/// table's buckets are about 8/7 of what it holds.
fn table_bytes(entries: usize, masks: usize) -> usize {
    entries * ENTRY_BYTES * 8 / 7 + masks * std::mem::size_of::<u64>()
}

/// One receiver root's kept verdicts.
#[derive(Debug, Clone, Default)]
pub struct NearVerdicts {
    entries: HashMap<LinkKey, Entry>,
    masks: Vec<u64>,
}

/// A link's kept verdicts, read back.
#[derive(Debug, Clone, Copy)]
pub(super) struct KnownVerdicts<'a> {
    entry: Entry,
    masks: &'a [u64],
}

impl KnownVerdicts<'_> {
    /// Point `k`'s ray mask (packing order of its rays, [`ALL_VISIBLE`] when all passed).
    pub fn seen(&self, k: usize) -> u64 {
        debug_assert!(k < usize::from(self.entry.points), "a point of the link");
        if self.entry.mixed != NO_MASKS {
            self.masks[self.entry.mixed as usize + k]
        } else if self.entry.visible >> k & 1 == 1 {
            ALL_VISIBLE
        } else {
            0
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
            masks: &self.masks,
        })
    }

    /// Keeps what a link's rays said (`seen`: each point's mask, `ALL_VISIBLE` for a point all
    /// of whose rays passed; `verdict_rays`: the oracle's answer, if it asked), within `budget`:
    /// a new entry, or the verdict rays' answer for a kept one that lacked it.
    pub(super) fn keep(
        &mut self,
        key: LinkKey,
        seen: &[u64],
        verdict_rays: Option<bool>,
        budget: &VerdictBudget,
    ) {
        debug_assert!(seen.len() <= MAX_POINTS.min(64));
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
        let masks_needed = self.masks.len() + if uniform { 0 } else { seen.len() };
        let masks_after = if masks_needed > self.masks.capacity() {
            (2 * self.masks.capacity()).max(masks_needed).max(4)
        } else {
            self.masks.capacity()
        };
        let reserved = table_bytes(entries_after, masks_after).saturating_sub(before);
        if !budget.reserve(reserved) {
            return;
        }
        let mixed = if uniform {
            NO_MASKS
        } else {
            // An offset that would reach `NO_MASKS` is not kept (some 32 GiB of one receiver's
            // masks).
            match u32::try_from(self.masks.len() + seen.len()) {
                Ok(end) if end < NO_MASKS => {
                    let start = self.masks.len() as u32;
                    self.masks.extend_from_slice(seen);
                    start
                }
                _ => {
                    budget.settle(reserved, 0);
                    return;
                }
            }
        };
        let visible = seen
            .iter()
            .enumerate()
            .fold(0u64, |v, (k, &m)| v | u64::from(m == ALL_VISIBLE) << k);
        self.entries.insert(
            key,
            Entry {
                visible,
                mixed,
                points: seen.len() as u8,
                verdict_rays: answer,
            },
        );
        budget.settle(reserved, self.bytes().saturating_sub(before));
    }

    /// Bytes the table takes (about: the hash table's buckets, its control bytes, the masks).
    pub fn bytes(&self) -> usize {
        table_bytes(self.entries.capacity(), self.masks.capacity())
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

    /// Uniform and mixed masks read back as kept, per point; the verdict rays' answer is kept
    /// once and never changed; other links are unknown.
    #[test]
    fn verdicts_read_back_as_kept() {
        let budget = VerdictBudget::new(usize::MAX);
        let mut t = NearVerdicts::default();
        let uniform = [ALL_VISIBLE, 0, ALL_VISIBLE, ALL_VISIBLE];
        let mixed = [0b1011, ALL_VISIBLE, 0, 0b1];
        t.keep(key(1), &uniform, None, &budget);
        t.keep(key(2), &mixed, Some(true), &budget);
        let a = t.known(&key(1)).expect("kept");
        let b = t.known(&key(2)).expect("kept");
        for k in 0..4 {
            assert_eq!(a.seen(k), uniform[k], "point {k}");
            assert_eq!(b.seen(k), mixed[k], "point {k}");
        }
        assert_eq!(a.verdict_rays(), None);
        assert_eq!(b.verdict_rays(), Some(true));
        t.keep(key(1), &[0; 4], Some(false), &budget);
        t.keep(key(2), &[0; 4], Some(false), &budget);
        let a = t.known(&key(1)).expect("kept");
        assert_eq!(a.seen(0), ALL_VISIBLE, "masks are never changed");
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

    /// Tables grow only while the budget holds their grown size; a full budget keeps nothing
    /// new, and what was kept stays readable.
    #[test]
    fn tables_stay_within_the_budget() {
        let limit = table_bytes(64, 32);
        let budget = VerdictBudget::new(limit);
        let mut tables = [NearVerdicts::default(), NearVerdicts::default()];
        for node in 0..1000 {
            let t = &mut tables[node % 2];
            t.keep(key(node), &[0b10; 8], None, &budget);
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
        t.keep(key(0), &[0; 4], None, &none);
        assert!(t.known(&key(0)).is_none());
    }
}
