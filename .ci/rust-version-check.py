#!/usr/bin/env python3
"""Fails when Cargo.toml's rust-version is older than a locked dependency needs.

Reads `cargo metadata --locked` (the resolved graph of Cargo.lock) and compares wavrad's
`rust-version` with the highest `rust-version` any package in the graph declares.
"""
import json
import subprocess
import sys


def version(text):
    parts = [int(p) for p in text.split(".")]
    return tuple(parts + [0] * (3 - len(parts)))


meta = json.loads(
    subprocess.run(
        ["cargo", "metadata", "--locked", "--format-version", "1"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
)
ours = next(p for p in meta["packages"] if p["name"] == "wavrad")
declared = ours.get("rust_version")
if not declared:
    sys.exit("Cargo.toml has no rust-version")
used = {p["id"] for p in meta["resolve"]["nodes"]}
need = max(
    ((version(p["rust_version"]), p["name"], p["version"]) for p in meta["packages"]
     if p.get("rust_version") and p["id"] in used and p["name"] != "wavrad"),
    default=((0,), "none", ""),
)
if version(declared) < need[0]:
    sys.exit(
        f"Cargo.toml says rust-version = {declared}, but {need[1]} {need[2]} needs "
        f"{'.'.join(map(str, need[0]))}: raise rust-version"
    )
print(f"rust-version {declared} covers every locked dependency (highest: {need[1]} {need[2]} needs {'.'.join(map(str, need[0]))})")
