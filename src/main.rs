//! The `penumbra` command; everything lives in the library.

fn main() -> std::process::ExitCode {
    penumbra::allocator::keep_freed_memory();
    penumbra::cli::main_with_args()
}
