//! Cluster mode of `wavrad serve` (`--database-url` + `--object-store`): N stateless replicas of
//! one binary share the jobs and the queue in PostgreSQL ([`db`]) and the uploads and outputs in
//! S3-compatible object storage ([`objects`]); [`worker`] claims, leases and solves jobs, and
//! [`routes`] answers every job route from the row and the object store, so any replica answers
//! for any job. The router swaps the local store's job handlers for these ones
//! (`crate::service::app`); without the flags nothing here runs.
//!
//! Invariants (pinned by `tests/real_clients/cluster.rs`):
//! - a job is solved by one replica at a time: a claim takes the oldest queued row with
//!   `FOR UPDATE SKIP LOCKED` and numbers the attempt; every later write of that claim carries the
//!   attempt number and is refused once a newer attempt exists (fencing);
//! - a finished job is never claimed again; a running job whose lease expired is queued again,
//!   or failed once `max_attempts` claims ended without finishing;
//! - the upload is in the object store before the 202, the outputs (under the attempt's own
//!   prefix) before the row says `succeeded`.

pub(crate) mod db;
pub(crate) mod objects;
pub(crate) mod routes;
pub(crate) mod worker;

use std::io;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

/// Lease of a claimed job when `--lease-seconds` is not given.
pub const DEFAULT_LEASE_SECONDS: u64 = 30;
/// Claims that may end without finishing (a replica died) before the job is failed.
pub const DEFAULT_MAX_ATTEMPTS: u32 = 3;
/// How often a running job's replica renews its lease, records its progress and reads the
/// job's cancel request (a cancel reaches the solver within this plus one solver check).
pub const HEARTBEAT: Duration = Duration::from_millis(500);
/// How often an idle replica looks for work without a notification (notifications are not
/// replayed to a replica that was disconnected) and for expired leases.
pub const POLL: Duration = Duration::from_secs(1);

/// The settings of cluster mode (`wavrad serve --database-url ... --object-store ...`).
#[derive(Clone, PartialEq, Eq)]
pub struct ClusterSettings {
    /// `postgres://user:password@host:port/db` (libpq key=value strings also work).
    pub database_url: String,
    /// `s3://BUCKET[/prefix]` (endpoint and credentials from the environment) or `file:///path`.
    pub object_store: String,
    /// Seconds a claim holds its job without a heartbeat.
    pub lease_seconds: u64,
    /// Claims of one job that may end without finishing before it is failed.
    pub max_attempts: u32,
}

impl ClusterSettings {
    pub fn new(database_url: impl Into<String>, object_store: impl Into<String>) -> Self {
        ClusterSettings {
            database_url: database_url.into(),
            object_store: object_store.into(),
            lease_seconds: DEFAULT_LEASE_SECONDS,
            max_attempts: DEFAULT_MAX_ATTEMPTS,
        }
    }

    /// Checks the settings; the error names the option.
    pub fn validate(&self) -> Result<(), String> {
        if self.lease_seconds < 2 {
            return Err(
                "--lease-seconds must be at least 2 (the heartbeat renews it twice a second)"
                    .into(),
            );
        }
        if self.max_attempts == 0 {
            return Err("--max-attempts must be at least 1".into());
        }
        objects::parse_url(&self.object_store).map(|_| ())
    }
}

impl std::fmt::Debug for ClusterSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClusterSettings")
            .field("database_url", &"<set>")
            .field("object_store", &self.object_store)
            .field("lease_seconds", &self.lease_seconds)
            .field("max_attempts", &self.max_attempts)
            .finish()
    }
}

/// A replica's handles on the shared state.
#[derive(Debug)]
pub struct Cluster {
    pub(crate) db: db::Db,
    pub(crate) objects: objects::Objects,
    pub(crate) settings: ClusterSettings,
    /// This replica's name in the rows it claims (`host:pid:random`).
    pub(crate) replica: String,
    /// Woken by a `NOTIFY` (a job was queued) so idle runners claim at once.
    pub(crate) wake: Notify,
    pub(crate) counters: ClusterCounters,
}

/// Per-replica counters for `/metrics`.
#[derive(Debug, Default)]
pub struct ClusterCounters {
    pub claims: std::sync::atomic::AtomicU64,
    pub lost_leases: std::sync::atomic::AtomicU64,
    pub cancels_seen: std::sync::atomic::AtomicU64,
}

impl Cluster {
    /// Connects to the database (applying the migrations) and opens the object store.
    pub async fn connect(settings: ClusterSettings) -> io::Result<Arc<Cluster>> {
        settings
            .validate()
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        let objects = objects::Objects::open(&settings.object_store)?;
        let db = db::Db::new(settings.database_url.clone());
        db.migrate().await.map_err(|e| {
            io::Error::other(format!(
                "cannot prepare the database at --database-url: {e}"
            ))
        })?;
        let replica = format!(
            "{}:{}:{:04x}",
            hostname(),
            std::process::id(),
            std::hash::BuildHasher::hash_one(&std::collections::hash_map::RandomState::new(), 0u8)
                & 0xffff
        );
        tracing::info!(%replica, object_store = %settings.object_store, "cluster mode: jobs in PostgreSQL");
        Ok(Arc::new(Cluster {
            db,
            objects,
            settings,
            replica,
            wake: Notify::new(),
            counters: ClusterCounters::default(),
        }))
    }

    pub fn lease(&self) -> Duration {
        Duration::from_secs(self.settings.lease_seconds)
    }
}

fn hostname() -> String {
    std::fs::read_to_string("/etc/hostname")
        .ok()
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "replica".into())
}
