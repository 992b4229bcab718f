//! The `compass-pdr` command line: the only code that knows files and argv.

#[cfg(not(target_arch = "wasm32"))]
mod cli;

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    cli::main()
}

// The page is the wasm32 program; this binary exists only natively.
#[cfg(target_arch = "wasm32")]
fn main() {}
