//! Running the `wavrad` binary built for these tests (`CARGO_BIN_EXE_wavrad`) and capturing its
//! exit status, stdout and stderr.

use std::process::{Command, Output};

/// Runs `wavrad ARGS...` to its end.
pub fn wavrad(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args(args)
        .output()
        .expect("the wavrad binary runs")
}
