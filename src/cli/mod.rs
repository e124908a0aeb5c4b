//! Subcommand implementations; each returns the process exit code of the contract
//! (0 ok, 1 a gate failed, 2 bad input).

use std::process::ExitCode;

pub mod batch_options;
pub mod bench;
pub mod calibrate;
pub mod demo;
pub mod detect;
pub mod kinematics;
pub mod measure;
pub mod merge;
pub mod render;
pub mod run;
pub mod suite;
pub mod sweep;

/// Exit code for bad input (the message names the file, key and reason).
pub const EXIT_BAD_INPUT: u8 = 2;

/// Marks an error as bad user input, so the process exits with code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Parses a `--min-success` rate: a number in [0, 1].
pub fn parse_rate(text: &str) -> Result<f64, String> {
    let rate: f64 = text
        .parse()
        .map_err(|e| format!("{text:?} is not a number ({e})"))?;
    if (0.0..=1.0).contains(&rate) {
        Ok(rate)
    } else {
        Err(format!("{rate} is not in [0, 1]"))
    }
}

/// Maps an error to the contract's exit code: 2 for bad input, 1 otherwise.
pub fn exit_code_for(err: &anyhow::Error) -> ExitCode {
    if err.chain().any(|cause| cause.is::<BadInput>()) {
        ExitCode::from(EXIT_BAD_INPUT)
    } else {
        ExitCode::from(1)
    }
}
