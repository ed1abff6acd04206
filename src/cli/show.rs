//! How a command's report reaches the terminal, and the progress bars of long commands.

use cncsim::command::{Ending, Report};
use indicatif::{ProgressBar, ProgressStyle};

/// Writes the report's files and shows it: its messages on the error stream, then the report
/// (text, or JSON with `json` where the command has a JSON form) and the files written (on the
/// error stream under JSON, so that the report stream is JSON alone). A file that cannot be
/// written makes the ending bad input.
pub fn show(report: &dyn Report, json: bool) -> Ending {
    let files = report.write();
    for line in report.messages() {
        eprintln!("{line}");
    }
    let as_json = report.json().filter(|_| json);
    match &as_json {
        Some(value) => println!(
            "{}",
            serde_json::to_string_pretty(value).expect("JSON of plain values")
        ),
        None => print!("{}", report.text()),
    }
    match files {
        Ok(files) => {
            for f in files {
                if as_json.is_some() {
                    eprintln!("  wrote {}", f.display());
                } else {
                    println!("  wrote {}", f.display());
                }
            }
            report.ending()
        }
        Err(e) => Ending::BadInput(Some(e.to_string())),
    }
}

/// A progress bar counting `what` (runs, candidates); `None`: a percentage bar for one run.
pub fn progress_bar(what: Option<&str>) -> ProgressBar {
    let template = match what {
        Some(what) => {
            format!("{{spinner}} [{{bar:30}}] {{pos}}/{{len}} {what} {{msg}} {{elapsed_precise}} eta {{eta}}")
        }
        None => "{spinner} {msg} [{bar:30}] {percent:>3}% {elapsed_precise} eta {eta}".into(),
    };
    ProgressBar::new(1).with_style(
        ProgressStyle::with_template(&template)
            .expect("valid template")
            .progress_chars("=> "),
    )
}
