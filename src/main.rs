//! The `sigmap` command; the library does the work.

fn main() {
    sigmap::heap::keep_freed_memory();
    std::process::exit(sigmap::cli::main());
}
