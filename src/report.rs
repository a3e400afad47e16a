//! Printing a command's report: one JSON object with `--json`, text otherwise.

use serde::Serialize;

/// An error a command reports to the user: one line that says what failed.
pub type CmdResult = Result<(), String>;

/// Prints `report` as one JSON object when `json`, else calls `text`.
pub fn emit<R: Serialize>(json: bool, report: &R, text: impl FnOnce(&R)) -> CmdResult {
    if json {
        let s = serde_json::to_string(report)
            .map_err(|e| format!("cannot encode the report as JSON: {e}"))?;
        println!("{s}");
    } else {
        text(report);
    }
    Ok(())
}

/// Rate per second, 0 when no time was measured.
pub fn per_second(count: f64, seconds: f64) -> f64 {
    if seconds > 0.0 {
        count / seconds
    } else {
        0.0
    }
}
