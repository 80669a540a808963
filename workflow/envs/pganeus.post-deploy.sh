#!/usr/bin/env bash
# Run by Snakemake once, when it creates the environment: the pganeus binary built into it.
set -euo pipefail
: "${PGANEUS_SOURCE:?set PGANEUS_SOURCE to the pganeus source tree (the folder with Cargo.toml)}"
cargo install --locked --path "$PGANEUS_SOURCE/crates/cli" --root "$CONDA_PREFIX"
