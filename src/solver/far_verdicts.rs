//! The shadow-ray verdicts of far links, kept from one indirect shot of a root to the next.
//!
//! A far link (`far_field.rs`) decides its visibility by one ray from the receiver's link point
//! to the shooter root's centre stand-in, ignoring the two faces: a verdict that depends on the
//! pair of roots alone, whatever the shooter's radiosity. A root shoots again and again as light
//! comes back to it, and most receivers of its shots are far ones, so the same rays were traced
//! shot after shot. Per shooter root, a table of two bits per receiver root (known, visible)
//! keeps them; a later shot reads the verdict instead of tracing it, and a pair known blocked
//! skips the link's form factor as well (a verdict is written only after the pair's form factor
//! was found positive, and that depends on the shooter root's geometry and cover and the
//! receiver's link point alone).
//!
//! Invariants: a verdict read is the one the ray would give (the solve is the same with or
//! without the tables: `tests/solver.rs`
//! `far_link_verdicts_kept_between_shots_change_no_light_and_save_rays`); the tables never
//! take more than the budget (`SolverParams::far_verdict_bytes`): a shooter whose table does not
//! fit traces its far links as before. Receivers write their bits concurrently (one atomic
//! `fetch_or` per new verdict; a verdict is never changed once written).

use std::sync::atomic::{AtomicU64, Ordering};

/// Receiver roots per 64-bit word of a table (two bits each).
const PER_WORD: usize = 32;

/// One shooter's verdicts, two bits per receiver root: bit 0 known, bit 1 visible.
pub(super) struct VerdictTable {
    words: Box<[AtomicU64]>,
}

impl VerdictTable {
    fn new(receivers: usize) -> Self {
        VerdictTable {
            words: (0..receivers.div_ceil(PER_WORD))
                .map(|_| AtomicU64::new(0))
                .collect(),
        }
    }

    fn bytes(receivers: usize) -> usize {
        receivers.div_ceil(PER_WORD) * std::mem::size_of::<AtomicU64>()
    }

    /// Receiver `r`'s verdict if a shot traced it: `Some(false)` blocked, `Some(true)` visible.
    pub fn known(&self, r: usize) -> Option<bool> {
        let (word, shift) = (&self.words[r / PER_WORD], 2 * (r % PER_WORD));
        let bits = word.load(Ordering::Relaxed) >> shift & 0b11;
        (bits & 1 == 1).then_some(bits == 0b11)
    }

    /// Whether receiver `r` sees the shooter, traced by `trace` the first time it is asked.
    pub fn visible(&self, r: usize, trace: impl FnOnce() -> bool) -> bool {
        let (word, shift) = (&self.words[r / PER_WORD], 2 * (r % PER_WORD));
        let bits = word.load(Ordering::Relaxed) >> shift & 0b11;
        if bits & 1 == 1 {
            return bits == 0b11;
        }
        let seen = trace();
        word.fetch_or((1 | u64::from(seen) << 1) << shift, Ordering::Relaxed);
        seen
    }
}

/// Every shooter's table, within a budget of bytes.
pub(super) struct FarVerdicts {
    tables: Vec<Option<VerdictTable>>,
    receivers: usize,
    bytes: usize,
    budget: usize,
}

impl FarVerdicts {
    /// No table yet for any of `roots` roots; at most `budget` bytes of tables.
    pub fn new(roots: usize, budget: usize) -> Self {
        FarVerdicts {
            tables: (0..roots).map(|_| None).collect(),
            receivers: roots,
            bytes: 0,
            budget,
        }
    }

    /// Makes room for shooter `s`'s table if it has none and the budget allows it.
    pub fn reserve(&mut self, s: usize) {
        let bytes = VerdictTable::bytes(self.receivers);
        if self.tables[s].is_none() && self.bytes + bytes <= self.budget {
            self.tables[s] = Some(VerdictTable::new(self.receivers));
            self.bytes += bytes;
        }
    }

    /// Shooter `s`'s table, when it has one.
    pub fn table(&self, s: usize) -> Option<&VerdictTable> {
        self.tables[s].as_ref()
    }

    /// Bytes the tables take.
    pub fn bytes(&self) -> usize {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    /// A verdict is traced once per pair and read back as traced, for receivers on both sides of
    /// a word's boundary; other receivers and shooters are not affected.
    #[test]
    fn a_verdict_is_traced_once_and_read_back() {
        let mut v = FarVerdicts::new(70, usize::MAX);
        v.reserve(3);
        assert!(v.table(2).is_none());
        let t = v.table(3).expect("a table within the budget");
        let traced = Cell::new(0);
        let trace = |seen: bool| {
            traced.set(traced.get() + 1);
            seen
        };
        for r in 0..70 {
            assert_eq!(t.known(r), None);
            assert_eq!(t.visible(r, || trace(r % 3 == 0)), r % 3 == 0);
        }
        assert_eq!(traced.get(), 70);
        for r in 0..70 {
            assert_eq!(t.known(r), Some(r % 3 == 0));
            assert_eq!(t.visible(r, || trace(r % 3 != 0)), r % 3 == 0);
        }
        assert_eq!(traced.get(), 70, "no second ray for a known pair");
    }

    /// Tables are made only within the budget, once per shooter.
    #[test]
    fn tables_stay_within_the_budget() {
        let one = VerdictTable::bytes(100);
        assert_eq!(one, 4 * 8);
        let mut v = FarVerdicts::new(100, 2 * one);
        for s in [5, 5, 7, 9] {
            v.reserve(s);
        }
        assert!(v.table(5).is_some() && v.table(7).is_some());
        assert!(v.table(9).is_none(), "over the budget: traced as before");
        assert_eq!(v.bytes(), 2 * one);
        let mut none = FarVerdicts::new(100, 0);
        none.reserve(0);
        assert!(none.table(0).is_none());
    }
}
