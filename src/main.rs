//! The `hooke` command (see `hooke --help`); everything it does lives in the `hooke-cli` crate.

fn main() -> std::process::ExitCode {
    hooke_cli::main()
}
