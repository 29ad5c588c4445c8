//! The `penumbra` command; everything lives in the library.

fn main() -> std::process::ExitCode {
    penumbra::internal::allocator::keep_freed_memory();
    penumbra::internal::cli::main_with_args()
}
