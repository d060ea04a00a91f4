#!/usr/bin/env bash
# Load benchmark of `wavrad serve` on loopback (needs `wrk`: apt-get install -y wrk).
#
#   bench/load.sh                      # builds the release binary if needed (honours CARGO_TARGET_DIR)
#   WAVRAD_BIN=target/debug/wavrad bench/load.sh
#   REPLICAS=2 WAVRAD_DATABASE_URL=postgres://... WAVRAD_OBJECT_STORE=s3://bucket/bench bench/load.sh
#       # cluster mode: two replicas on the same database and object store (AWS_* variables for
#       # S3; use a fresh database or prefix); the solve runs on one of them, the GETs go to the
#       # second replica and the POSTs to the first, and the same table is printed.
#
# 1. starts the server on a free port with a fresh data dir (--max-queued $MAX_QUEUED);
# 2. submits one long solve (the bundled Kenney scene at order 3, small tolerance, 120 s budget)
#    and waits until it is running: the solver pool now saturates every core;
# 3. wrk, 64 connections for $DURATION s: GET /v1/jobs/{id} -> requests/s and p99 latency;
# 4. wrk, 16 connections: POST /v1/jobs (a small scene) until the queue is full (each wrk thread
#    stops at its first 429; wrk itself still runs out its 15 s) -> p99 latency of the submissions;
# 5. prints the solve's state after each phase (it must say running) and stops the server.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${WAVRAD_BIN:-${CARGO_TARGET_DIR:-target}/release/wavrad}
DURATION=${DURATION:-10}
MAX_QUEUED=${MAX_QUEUED:-500}
LONG_SCENE=${LONG_SCENE:-scenes/kenney_building_small_c/kenney_building_small_c_lit.glb}
SMALL_SCENE=${SMALL_SCENE:-tests/data/analytic/furnace.glb}
command -v wrk >/dev/null || { echo "wrk is missing: apt-get install -y wrk" >&2; exit 2; }
[ -x "$BIN" ] || cargo build --release --locked

REPLICAS=${REPLICAS:-1}
if [ "$REPLICAS" -gt 1 ] && { [ -z "${WAVRAD_DATABASE_URL:-}" ] || [ -z "${WAVRAD_OBJECT_STORE:-}" ]; }; then
  echo "REPLICAS=$REPLICAS needs WAVRAD_DATABASE_URL and WAVRAD_OBJECT_STORE (cluster mode)" >&2
  exit 2
fi
[ "$REPLICAS" -gt 1 ] || unset WAVRAD_DATABASE_URL WAVRAD_OBJECT_STORE

DATA=$(mktemp -d)
PIDS=()
trap 'for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; wait "$p" 2>/dev/null; done; rm -rf "$DATA"' EXIT
BASES=()
for r in $(seq "$REPLICAS"); do
  "$BIN" serve --addr 127.0.0.1:0 --data-dir "$DATA/data-$r" --max-queued "$MAX_QUEUED" \
      >"$DATA/stdout-$r" 2>"$DATA/server-$r.log" &
  PIDS+=($!)
  for _ in $(seq 100); do [ -s "$DATA/stdout-$r" ] && break; sleep 0.1; done
  ADDR=$(sed -n 's/.*"listening":"\([^"]*\)".*/\1/p' "$DATA/stdout-$r")
  [ -n "$ADDR" ] || { echo "replica $r did not start:" >&2; cat "$DATA/server-$r.log" >&2; exit 1; }
  BASES+=("http://$ADDR")
done
BASE=${BASES[0]}
# The polling goes to the last replica (in cluster mode, one that may not run the solve).
READ_BASE=${BASES[$((REPLICAS - 1))]}
echo "server: ${BASES[*]} ($(nproc) cores)"

state() { curl -s "$BASE/v1/jobs/$1" | sed -n 's/.*"state":"\([a-z]*\)".*/\1/p'; }
ID=$(curl -s -X POST -H 'Content-Type: model/gltf-binary' --data-binary @"$LONG_SCENE" \
    "$BASE/v1/jobs?order=3&tolerance=1e-5&target_unshot=1e-7&max_seconds=120" |
    sed -n 's/.*"id":"\([0-9a-f]*\)".*/\1/p')
for _ in $(seq 200); do [ "$(state "$ID")" = running ] && break; sleep 0.1; done
[ "$(state "$ID")" = running ] || { echo "the solve did not start" >&2; exit 1; }
sleep 1
echo "solve $ID running: $(curl -s "$BASE/v1/jobs/$ID" | sed -n 's/.*"progress":\({[^}]*}\).*/\1/p')"

echo "--- GET /v1/jobs/{id}, 64 connections, ${DURATION} s, while the solve runs"
wrk -t2 -c64 -d"${DURATION}s" --latency "$READ_BASE/v1/jobs/$ID" >"$DATA/get.txt"
grep -E "Requests/sec|^ +99%|^ +50%|Non-2xx|Socket errors" "$DATA/get.txt" | sed 's/^ */  /'
echo "  the solve after polling: $(state "$ID")"

echo "--- POST /v1/jobs, 16 connections, until the queue ($MAX_QUEUED) is full"
SCENE="$SMALL_SCENE" wrk -t2 -c16 -d15s --latency -s bench/post.lua "$BASE/v1/jobs" >"$DATA/post.txt"
grep -E "^POST|Socket errors" "$DATA/post.txt" | sed 's/^ */  /'
echo "  the solve after the submissions: $(state "$ID")"

echo "--- the solve now: $(state "$ID"), $(curl -s "$BASE/v1/jobs/$ID" | sed -n 's/.*"progress":\({[^}]*}\).*/\1/p')"
for b in "${BASES[@]}"; do
  curl -s "$b/metrics" | grep -E '^wavrad_(queue_depth|running_shots|cluster_claims_total|cluster_running) '
done
