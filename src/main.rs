//! The `sigmap` command; the library does the work.

fn main() {
    std::process::exit(sigmap::cli::main());
}
