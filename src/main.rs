//! The `springfit` command line. A thin shell around the library: parse arguments, run the
//! command, print one error line and exit with a documented code (0 ok, 1 the design could not
//! be met, 2 bad input or usage).

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("springfit: error: {}", cli::describe(&e));
            ExitCode::from(cli::exit_code(&e))
        }
    }
}
