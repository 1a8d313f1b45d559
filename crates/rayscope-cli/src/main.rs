//! The `rayscope` binary; the command line itself is the crate's library ([`rayscope_cli`]).

fn main() -> std::process::ExitCode {
    rayscope_cli::main()
}
