//! The `wavrad` binary: see `wavrad::cli`.

fn main() -> std::process::ExitCode {
    wavrad::cli::main_with_args(std::env::args_os())
}
