//! Running the `wavrad` binary built for these tests (`CARGO_BIN_EXE_wavrad`) and capturing its
//! exit status, stdout and stderr.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `wavrad solve SCENE --out OUT EXTRA...` and asserts it exited 0 (its stderr otherwise).
pub fn solve_ok(scene: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "solve",
        scene.to_str().expect("a UTF-8 path"),
        "--out",
        out.to_str().expect("a UTF-8 path"),
    ];
    args.extend_from_slice(extra);
    let run = wavrad(&args);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    run
}

/// Runs `wavrad ARGS...` to its end.
pub fn wavrad(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args(args)
        .output()
        .expect("the wavrad binary runs")
}
