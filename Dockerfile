# wavrad service image: build with the same command the README uses, run `wavrad serve`.
# Build:  docker build -t wavrad .
# Run:    docker run -p 8080:8080 -v wavrad-data:/data wavrad
# Cluster: docker-compose.yml runs two replicas on PostgreSQL and SeaweedFS (README, "Scaling out").
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY api ./api
# The database migrations of cluster mode, embedded in the binary (src/service/cluster/db.rs).
COPY migrations ./migrations
COPY scenes ./scenes
# Cargo.toml declares the benches, so their sources must be present for the manifest to load
# (only the binary is built). Tests and examples are not needed.
COPY benches ./benches
RUN cargo build --release --locked --bin wavrad

FROM debian:bookworm-slim
# curl answers the health check (GET /healthz); the slim image has no HTTP client of its own.
RUN apt-get update \
    && apt-get install -y --no-install-recommends curl ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --uid 10001 --home /data wavrad \
    && mkdir -p /data && chown wavrad /data
COPY --from=build /src/target/release/wavrad /usr/local/bin/wavrad
COPY --from=build /src/scenes /usr/share/wavrad/scenes
USER wavrad
VOLUME ["/data"]
EXPOSE 8080
ENV RUST_LOG=info
# The health check asks the address CMD listens on; change both together (`--addr`).
HEALTHCHECK --interval=30s --timeout=3s --start-period=10s CMD ["curl", "-fsS", "http://127.0.0.1:8080/healthz"]
ENTRYPOINT ["/usr/local/bin/wavrad"]
CMD ["serve", "--addr", "0.0.0.0:8080", "--data-dir", "/data"]
