//! The `penumbra` command; everything lives in the library.

fn main() -> std::process::ExitCode {
    penumbra::cli::main_with_args()
}
