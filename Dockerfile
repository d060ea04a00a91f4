# wavrad service image: build with the same command the README uses, run `wavrad serve`.
# Build:  docker build -t wavrad .
# Run:    docker run -p 8080:8080 -v wavrad-data:/data wavrad
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY api ./api
COPY scenes ./scenes
# Cargo.toml declares the benches, so their sources must be present for the manifest to load
# (only the binary is built). Tests and examples are not needed.
COPY benches ./benches
RUN cargo build --release --locked --bin wavrad

FROM debian:bookworm-slim
RUN useradd --system --uid 10001 --home /data wavrad \
    && mkdir -p /data && chown wavrad /data
COPY --from=build /src/target/release/wavrad /usr/local/bin/wavrad
COPY --from=build /src/scenes /usr/share/wavrad/scenes
USER wavrad
VOLUME ["/data"]
EXPOSE 8080
ENV RUST_LOG=info
HEALTHCHECK --interval=30s --timeout=3s CMD ["/usr/local/bin/wavrad", "--version"]
ENTRYPOINT ["/usr/local/bin/wavrad"]
CMD ["serve", "--addr", "0.0.0.0:8080", "--data-dir", "/data"]
