//! PostgreSQL of cluster mode: one reconnecting connection per replica (tokio-postgres pipelines
//! concurrent queries on it), the migrations of `migrations/` applied at start under an advisory
//! lock, and every statement on the `jobs` table, which is the queue.
//!
//! Fencing: every statement a claim makes after it (heartbeat, finish, release) names the job and
//! its attempt number and matches only while the row is `running` with that attempt; a replica
//! whose lease expired and was claimed again gets zero rows and stops.

use super::super::error::ErrorBody;
use super::super::jobs::{JobLinks, JobState, JobView, ProgressView};
use super::super::time::rfc3339;
use crate::job::JobParams;
use std::sync::Arc;
use std::time::SystemTime;
use tokio_postgres::{Client, NoTls, Row};

/// The migrations, in order: (version, SQL). Each runs once (recorded in `wavrad_migrations`).
const MIGRATIONS: &[(i32, &str)] = &[(1, include_str!("../../../migrations/0001_jobs.sql"))];

/// Advisory lock key held while migrating, so replicas starting together do not race.
const MIGRATION_LOCK: i64 = 0x7761_7672_6164; // "wavrad"

/// The channel a submission notifies so idle replicas claim at once.
pub const NOTIFY_CHANNEL: &str = "wavrad_jobs";

pub type DbError = tokio_postgres::Error;

/// A reconnecting connection.
#[derive(Debug)]
pub struct Db {
    url: String,
    client: tokio::sync::Mutex<Option<Arc<Client>>>,
}

/// The columns every job query returns.
const JOB_COLUMNS: &str = "id, name, created, params, state, attempt, progress, error, \
     stop_reason, result_attempt, parts, input_name, request_hash";

/// One row of `jobs`.
#[derive(Debug, Clone)]
pub struct JobRow {
    pub id: String,
    pub name: Option<String>,
    pub created: SystemTime,
    pub params: JobParams,
    pub state: JobState,
    pub attempt: i32,
    pub progress: ProgressView,
    pub error: Option<ErrorBody>,
    pub stop_reason: Option<String>,
    pub result_attempt: Option<i32>,
    /// The multipart upload's extra files: URI -> object name.
    pub parts: std::collections::BTreeMap<String, String>,
    pub input_name: String,
    pub request_hash: Option<String>,
}

fn parse_state(s: &str) -> JobState {
    match s {
        "queued" => JobState::Queued,
        "running" => JobState::Running,
        "succeeded" => JobState::Succeeded,
        "cancelled" => JobState::Cancelled,
        _ => JobState::Failed,
    }
}

impl JobRow {
    fn from_row(row: &Row) -> Result<JobRow, DbError> {
        let params: serde_json::Value = row.try_get("params")?;
        let progress: Option<serde_json::Value> = row.try_get("progress")?;
        let error: Option<serde_json::Value> = row.try_get("error")?;
        let parts: serde_json::Value = row.try_get("parts")?;
        let state: String = row.try_get("state")?;
        Ok(JobRow {
            id: row.try_get("id")?,
            name: row.try_get("name")?,
            created: row.try_get("created")?,
            params: serde_json::from_value(params).unwrap_or_default(),
            state: parse_state(&state),
            attempt: row.try_get("attempt")?,
            progress: progress
                .and_then(|p| serde_json::from_value(p).ok())
                .unwrap_or_default(),
            error: error.and_then(|e| serde_json::from_value(e).ok()),
            stop_reason: row.try_get("stop_reason")?,
            result_attempt: row.try_get("result_attempt")?,
            parts: serde_json::from_value(parts).unwrap_or_default(),
            input_name: row.try_get("input_name")?,
            request_hash: row.try_get("request_hash")?,
        })
    }

    /// The job document of the HTTP API (the same shape as the local store's).
    pub fn view(&self) -> JobView {
        let base = format!("/v1/jobs/{}", self.id);
        let mut progress = self.progress;
        if self.state.is_finished() {
            progress.eta_seconds = None;
        }
        JobView {
            id: self.id.clone(),
            name: self.name.clone(),
            state: self.state,
            created: rfc3339(self.created),
            params: self.params.clone(),
            progress,
            error: self.error.clone(),
            stop_reason: self.stop_reason.clone(),
            attempts: u32::try_from(self.attempt).unwrap_or(0),
            links: JobLinks {
                result: format!("{base}/result"),
                lightmap: format!("{base}/lightmap.exr"),
                convergence: format!("{base}/convergence"),
                self_: base,
            },
        }
    }
}

/// A new job's row.
#[derive(Debug)]
pub struct NewJob<'a> {
    pub id: &'a str,
    pub name: Option<&'a str>,
    pub created: SystemTime,
    pub params: &'a JobParams,
    pub input_name: &'a str,
    pub parts: &'a std::collections::BTreeMap<String, String>,
    pub idempotency_key: Option<&'a str>,
    pub request_hash: &'a str,
}

/// How an attempt ended, as written by its replica.
#[derive(Debug)]
pub struct Finish<'a> {
    pub state: JobState,
    pub stop_reason: Option<&'a str>,
    pub progress: Option<&'a ProgressView>,
    pub error: Option<&'a ErrorBody>,
    pub result_attempt: Option<i32>,
}

impl Db {
    pub fn new(url: String) -> Db {
        Db {
            url,
            client: tokio::sync::Mutex::new(None),
        }
    }

    /// The connection, opened again when it closed (PostgreSQL restarted).
    pub async fn client(&self) -> Result<Arc<Client>, DbError> {
        let mut slot = self.client.lock().await;
        if let Some(client) = slot.as_ref() {
            if !client.is_closed() {
                return Ok(client.clone());
            }
        }
        let client = Arc::new(connect(&self.url).await?);
        *slot = Some(client.clone());
        Ok(client)
    }

    /// Applies the migrations not yet applied, under an advisory lock (on a connection of its own,
    /// so the lock ends with it whatever happens).
    pub async fn migrate(&self) -> Result<(), DbError> {
        let client = connect(&self.url).await?;
        client
            .execute("SELECT pg_advisory_lock($1)", &[&MIGRATION_LOCK])
            .await?;
        client
            .batch_execute(
                "CREATE TABLE IF NOT EXISTS wavrad_migrations (version integer PRIMARY KEY, \
                 applied timestamptz NOT NULL DEFAULT now())",
            )
            .await?;
        for (version, sql) in MIGRATIONS {
            let done = client
                .query_opt(
                    "SELECT 1 FROM wavrad_migrations WHERE version = $1",
                    &[version],
                )
                .await?
                .is_some();
            if done {
                continue;
            }
            client.batch_execute(sql).await?;
            client
                .execute(
                    "INSERT INTO wavrad_migrations (version) VALUES ($1)",
                    &[version],
                )
                .await?;
            tracing::info!(version, "database migration applied");
        }
        client
            .execute("SELECT pg_advisory_unlock($1)", &[&MIGRATION_LOCK])
            .await?;
        Ok(())
    }

    pub async fn get(&self, id: &str) -> Result<Option<JobRow>, DbError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = $1");
        let row = self.client().await?.query_opt(&sql, &[&id]).await?;
        row.as_ref().map(JobRow::from_row).transpose()
    }

    pub async fn by_key(&self, key: &str) -> Result<Option<JobRow>, DbError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE idempotency_key = $1");
        let row = self.client().await?.query_opt(&sql, &[&key]).await?;
        row.as_ref().map(JobRow::from_row).transpose()
    }

    /// Every job, newest first.
    pub async fn list(&self) -> Result<Vec<JobRow>, DbError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs ORDER BY created DESC, seq DESC");
        let rows = self.client().await?.query(&sql, &[]).await?;
        rows.iter().map(JobRow::from_row).collect()
    }

    pub async fn queued(&self) -> Result<i64, DbError> {
        let row = self
            .client()
            .await?
            .query_one("SELECT count(*) FROM jobs WHERE state = 'queued'", &[])
            .await?;
        row.try_get(0)
    }

    /// Inserts a job and notifies idle replicas; None when its idempotency key is already taken.
    pub async fn insert(&self, job: &NewJob<'_>) -> Result<Option<JobRow>, DbError> {
        let params = serde_json::to_value(job.params).unwrap_or_default();
        let parts = serde_json::to_value(job.parts).unwrap_or_default();
        let sql = format!(
            "INSERT INTO jobs (id, name, created, params, input_name, parts, idempotency_key, \
             request_hash) VALUES ($1, $2, $3, $4, $5, $6, $7, $8) \
             ON CONFLICT (idempotency_key) DO NOTHING RETURNING {JOB_COLUMNS}"
        );
        let client = self.client().await?;
        let row = client
            .query_opt(
                &sql,
                &[
                    &job.id,
                    &job.name,
                    &job.created,
                    &params,
                    &job.input_name,
                    &parts,
                    &job.idempotency_key,
                    &job.request_hash,
                ],
            )
            .await?;
        if row.is_some() {
            client
                .execute("SELECT pg_notify($1, $2)", &[&NOTIFY_CHANNEL, &job.id])
                .await?;
        }
        row.as_ref().map(JobRow::from_row).transpose()
    }

    /// Requeues (or fails, after `max_attempts` claims that did not finish) running jobs whose
    /// lease expired; their attempt rows end `lease_expired`. Returns how many.
    pub async fn sweep_expired(&self, max_attempts: u32) -> Result<u64, DbError> {
        let max = i32::try_from(max_attempts).unwrap_or(i32::MAX);
        let sql = "WITH expired AS ( \
               UPDATE jobs SET failures = failures + 1, replica = NULL, lease_until = NULL, \
                 state = CASE WHEN cancel_requested THEN 'cancelled' \
                   WHEN failures + 1 >= $1 THEN 'failed' ELSE 'queued' END, \
                 error = CASE WHEN NOT cancel_requested AND failures + 1 >= $1 THEN jsonb_build_object('code', \
                   'attempts_exhausted', 'message', 'the job was claimed ' || (failures + 1) || \
                   ' times and each time its replica stopped renewing its lease (it died or lost \
                   the database) before finishing; --max-attempts is ' || $1) ELSE error END \
               WHERE state = 'running' AND lease_until < now() RETURNING id, attempt) \
             UPDATE job_attempts a SET finished = now(), outcome = 'lease_expired' \
             FROM expired e WHERE a.job_id = e.id AND a.attempt = e.attempt";
        self.client().await?.execute(sql, &[&max]).await
    }

    /// Claims the oldest queued job: running, attempt + 1, leased to `replica`; its attempt row
    /// is inserted in the same statement.
    pub async fn claim(
        &self,
        replica: &str,
        lease_seconds: f64,
    ) -> Result<Option<JobRow>, DbError> {
        let sql = format!(
            "WITH next AS (SELECT id FROM jobs WHERE state = 'queued' ORDER BY seq LIMIT 1 \
               FOR UPDATE SKIP LOCKED), \
             claimed AS (UPDATE jobs j SET state = 'running', attempt = j.attempt + 1, \
               replica = $1, lease_until = now() + make_interval(secs => $2), \
               progress = NULL FROM next WHERE j.id = next.id RETURNING j.*), \
             attempt_row AS (INSERT INTO job_attempts (job_id, attempt, replica) \
               SELECT id, attempt, $1 FROM claimed) \
             SELECT {JOB_COLUMNS} FROM claimed"
        );
        let row = self
            .client()
            .await?
            .query_opt(&sql, &[&replica, &lease_seconds])
            .await?;
        row.as_ref().map(JobRow::from_row).transpose()
    }

    /// The heartbeat: renews the lease and records the progress. Some(cancel requested) while
    /// this attempt still holds the job, None once it does not (fenced out).
    pub async fn heartbeat(
        &self,
        id: &str,
        attempt: i32,
        lease_seconds: f64,
        progress: &ProgressView,
    ) -> Result<Option<bool>, DbError> {
        let progress = serde_json::to_value(progress).unwrap_or_default();
        let row = self
            .client()
            .await?
            .query_opt(
                "UPDATE jobs SET lease_until = now() + make_interval(secs => $3), progress = $4 \
                 WHERE id = $1 AND attempt = $2 AND state = 'running' RETURNING cancel_requested",
                &[&id, &attempt, &lease_seconds, &progress],
            )
            .await?;
        row.map(|r| r.try_get(0)).transpose()
    }

    /// Ends attempt `attempt`; false when a newer attempt holds the job (nothing written).
    pub async fn finish(&self, id: &str, attempt: i32, end: &Finish<'_>) -> Result<bool, DbError> {
        let progress = end
            .progress
            .map(|p| serde_json::to_value(p).unwrap_or_default());
        let error = end
            .error
            .map(|e| serde_json::to_value(e).unwrap_or_default());
        let state = end.state.as_str();
        let row = self
            .client()
            .await?
            .query_one(
                "WITH done AS (UPDATE jobs SET state = $3, stop_reason = $4, \
                   progress = COALESCE($5, progress), error = $6, result_attempt = $7, \
                   lease_until = NULL WHERE id = $1 AND attempt = $2 AND state = 'running' \
                   RETURNING id), \
                 attempt_row AS (UPDATE job_attempts SET finished = now(), outcome = $3 \
                   WHERE job_id IN (SELECT id FROM done) AND attempt = $2) \
                 SELECT count(*) FROM done",
                &[
                    &id,
                    &attempt,
                    &state,
                    &end.stop_reason,
                    &progress,
                    &error,
                    &end.result_attempt,
                ],
            )
            .await?;
        Ok(row.try_get::<_, i64>(0)? == 1)
    }

    /// Gives a running job back to the queue (the replica is shutting down); fenced like
    /// [`Db::finish`].
    pub async fn release(&self, id: &str, attempt: i32) -> Result<bool, DbError> {
        let row = self
            .client()
            .await?
            .query_one(
                "WITH back AS (UPDATE jobs SET state = 'queued', replica = NULL, \
                   lease_until = NULL, progress = NULL WHERE id = $1 AND attempt = $2 \
                   AND state = 'running' RETURNING id), \
                 attempt_row AS (UPDATE job_attempts SET finished = now(), outcome = 'released' \
                   WHERE job_id IN (SELECT id FROM back) AND attempt = $2) \
                 SELECT count(*) FROM back",
                &[&id, &attempt],
            )
            .await?;
        if row.try_get::<_, i64>(0)? == 1 {
            self.client()
                .await?
                .execute("SELECT pg_notify($1, $2)", &[&NOTIFY_CHANNEL, &id])
                .await?;
            return Ok(true);
        }
        Ok(false)
    }

    /// A client's cancel: a queued job ends `cancelled` here, a running one gets the request its
    /// replica's heartbeat reads. The row after the change, None when the job is not there or
    /// already finished.
    pub async fn cancel(&self, id: &str) -> Result<Option<JobRow>, DbError> {
        let sql = format!(
            "UPDATE jobs SET cancel_requested = true, \
               state = CASE WHEN state = 'queued' THEN 'cancelled' ELSE state END \
             WHERE id = $1 AND state IN ('queued', 'running') RETURNING {JOB_COLUMNS}"
        );
        let row = self.client().await?.query_opt(&sql, &[&id]).await?;
        row.as_ref().map(JobRow::from_row).transpose()
    }

    /// Deletes a finished job's row; false when it is not there or not finished.
    pub async fn delete_finished(&self, id: &str) -> Result<bool, DbError> {
        let n = self
            .client()
            .await?
            .execute(
                "DELETE FROM jobs WHERE id = $1 AND state IN ('succeeded', 'failed', 'cancelled')",
                &[&id],
            )
            .await?;
        Ok(n == 1)
    }
}

/// Opens a connection and drives it on a task of its own.
pub async fn connect(url: &str) -> Result<Client, DbError> {
    let (client, connection) = tokio_postgres::connect(url, NoTls).await?;
    tokio::spawn(async move {
        if let Err(e) = connection.await {
            tracing::warn!(error = %e, "database connection closed");
        }
    });
    Ok(client)
}

/// Listens on [`NOTIFY_CHANNEL`] and wakes idle runners at each notification, reconnecting after
/// a failure (the runners poll meanwhile).
pub async fn listen(url: String, wake: Arc<super::Cluster>) {
    loop {
        match tokio_postgres::connect(&url, NoTls).await {
            Ok((client, mut connection)) => {
                let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
                let driver = tokio::spawn(async move {
                    let mut messages =
                        futures_util::stream::poll_fn(move |cx| connection.poll_message(cx));
                    while let Some(message) = futures_util::StreamExt::next(&mut messages).await {
                        match message {
                            Ok(tokio_postgres::AsyncMessage::Notification(_)) => {
                                let _ = tx.send(());
                            }
                            Ok(_) => {}
                            Err(e) => {
                                tracing::warn!(error = %e, "the LISTEN connection failed");
                                break;
                            }
                        }
                    }
                });
                let listening = client
                    .batch_execute(&format!("LISTEN {NOTIFY_CHANNEL}"))
                    .await;
                if listening.is_ok() {
                    while rx.recv().await.is_some() {
                        wake.wake.notify_waiters();
                    }
                }
                driver.abort();
            }
            Err(e) => tracing::debug!(error = %e, "cannot open the LISTEN connection"),
        }
        tokio::time::sleep(super::POLL).await;
    }
}
