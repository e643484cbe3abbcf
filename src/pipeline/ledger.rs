//! At-least-once bookkeeping for a partitioned source (Kafka): the partitions this
//! member holds, each under a lease of its own, the offsets of the frames in flight, and
//! the receipt each frame carries until its record is written. Nothing here talks to a
//! broker, so the stages and sinks know receipts without knowing Kafka.

// Only a Kafka source grants leases and reads offsets.
#![cfg_attr(not(feature = "kafka"), allow(dead_code))]

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError, RwLock};

pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The partitions this member holds, each under the lease it was given with. A lease
/// is never reused, so state built under one assignment is never taken for another's.
#[derive(Debug, Default)]
pub struct Leases {
    held: RwLock<HashMap<i32, u64>>,
    last: AtomicU64,
}

impl Leases {
    pub(crate) fn grant(&self, partition: i32) -> u64 {
        let lease = self.last.fetch_add(1, Ordering::Relaxed) + 1;
        self.held
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(partition, lease);
        lease
    }

    pub(crate) fn revoke(&self, partition: i32) {
        self.held
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&partition);
    }

    /// How many partitions are held.
    pub(crate) fn count(&self) -> usize {
        self.held
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .len()
    }

    pub(crate) fn of(&self, partition: i32) -> Option<u64> {
        self.held
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&partition)
            .copied()
    }

    /// Whether the partition given under `lease` is still held.
    pub fn is_live(&self, lease: u64) -> bool {
        self.held
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .values()
            .any(|&l| l == lease)
    }
}

/// One held partition's offsets: those read and not yet written, and where the commits
/// stand.
#[derive(Debug)]
struct Track {
    lease: u64,
    pending: BTreeSet<i64>,
    /// One past the last offset read.
    next: Option<i64>,
    committed: Option<i64>,
}

impl Track {
    /// The offset to commit: the first one not written yet, or past everything read.
    fn position(&self) -> Option<i64> {
        self.pending.first().copied().or(self.next)
    }
}

/// The offsets of the frames in the pipeline, per held partition.
#[derive(Debug, Default)]
pub(crate) struct Ledger {
    parts: Mutex<HashMap<i32, Track>>,
}

impl Ledger {
    pub(crate) fn open(&self, partition: i32, lease: u64) {
        lock(&self.parts).insert(
            partition,
            Track {
                lease,
                pending: BTreeSet::new(),
                next: None,
                committed: None,
            },
        );
    }

    /// Notes a frame read; false if the partition is not held under `lease`.
    pub(crate) fn read(&self, partition: i32, lease: u64, offset: i64) -> bool {
        match lock(&self.parts).get_mut(&partition) {
            Some(t) if t.lease == lease => {
                t.pending.insert(offset);
                t.next = Some(t.next.map_or(offset + 1, |n| n.max(offset + 1)));
                true
            }
            _ => false,
        }
    }

    /// Notes a frame's record written. A frame of a partition given up meanwhile is
    /// ignored: its new owner reads it again.
    pub(crate) fn done(&self, partition: i32, lease: u64, offset: i64) {
        if let Some(t) = lock(&self.parts).get_mut(&partition) {
            if t.lease == lease {
                t.pending.remove(&offset);
            }
        }
    }

    /// The partitions whose commit position moved, with that position.
    pub(crate) fn due(&self) -> Vec<(i32, i64)> {
        let parts = lock(&self.parts);
        let mut due: Vec<(i32, i64)> = parts
            .iter()
            .filter_map(|(&p, t)| {
                t.position()
                    .filter(|&o| Some(o) != t.committed)
                    .map(|o| (p, o))
            })
            .collect();
        due.sort_unstable();
        due
    }

    /// Each tracked partition's position as last sent to the broker in a commit.
    pub(crate) fn queued(&self) -> Vec<(i32, i64)> {
        let parts = lock(&self.parts);
        let mut queued: Vec<(i32, i64)> = parts
            .iter()
            .filter_map(|(&p, t)| t.committed.map(|o| (p, o)))
            .collect();
        queued.sort_unstable();
        queued
    }

    pub(crate) fn committed(&self, positions: &[(i32, i64)]) {
        let mut parts = lock(&self.parts);
        for (p, o) in positions {
            if let Some(t) = parts.get_mut(p) {
                t.committed = Some(*o);
            }
        }
    }

    /// Stops tracking a partition; its position, if it read anything (committed or not:
    /// a commit is only known to have reached the broker once it answered).
    pub(crate) fn close(&self, partition: i32) -> Option<i64> {
        lock(&self.parts).remove(&partition)?.position()
    }

    /// Stops tracking every partition (the member is leaving and has committed what it
    /// could): nothing is left for a revocation to commit.
    pub(crate) fn close_all(&self) {
        lock(&self.parts).clear();
    }

    /// Frames read and not yet written.
    pub(crate) fn in_flight(&self) -> usize {
        lock(&self.parts).values().map(|t| t.pending.len()).sum()
    }
}

/// A frame's claim on its input offset: handed in when the frame's record is written,
/// after which the offset may be committed. Dropped unwritten, the offset stays
/// uncommitted and the frame is read again after a restart or a hand-over.
pub struct Receipt {
    pub(crate) ledger: Arc<Ledger>,
    pub(crate) partition: i32,
    pub(crate) lease: u64,
    pub(crate) offset: i64,
}

impl std::fmt::Debug for Receipt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Receipt(partition {} offset {} lease {})",
            self.partition, self.offset, self.lease
        )
    }
}

impl Receipt {
    /// The lease of the frame's partition.
    pub fn lease(&self) -> u64 {
        self.lease
    }

    /// The frame's record is written.
    pub fn done(self) {
        self.ledger.done(self.partition, self.lease, self.offset);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commits_stop_at_the_first_frame_not_written() {
        let ledger = Arc::new(Ledger::default());
        ledger.open(0, 1);
        for o in 10..14 {
            assert!(ledger.read(0, 1, o));
        }
        assert!(!ledger.read(1, 1, 0), "a partition not held");
        assert!(!ledger.read(0, 2, 14), "an older lease");
        assert_eq!(ledger.due(), vec![(0, 10)]);
        ledger.done(0, 1, 11);
        ledger.done(0, 1, 12);
        assert_eq!(
            ledger.due(),
            vec![(0, 10)],
            "10 is not written: nothing past it"
        );
        ledger.committed(&[(0, 10)]);
        assert_eq!(ledger.due(), vec![]);
        ledger.done(0, 1, 10);
        assert_eq!(ledger.due(), vec![(0, 13)]);
        ledger.done(0, 2, 13);
        assert_eq!(
            ledger.in_flight(),
            1,
            "a receipt of another lease counts for nothing"
        );
        ledger.done(0, 1, 13);
        assert_eq!(ledger.due(), vec![(0, 14)]);
        assert_eq!(ledger.close(0), Some(14));
        assert_eq!(ledger.due(), vec![]);
    }

    #[test]
    fn every_assignment_gets_a_new_lease() {
        let leases = Leases::default();
        let a = leases.grant(3);
        assert!(leases.is_live(a));
        leases.revoke(3);
        assert!(!leases.is_live(a));
        let b = leases.grant(3);
        assert_ne!(a, b);
        assert!(leases.is_live(b) && !leases.is_live(a));
        assert_eq!(leases.of(3), Some(b));
    }
}
