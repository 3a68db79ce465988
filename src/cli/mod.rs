//! The command-line front ends of the pipeline. Each subcommand is a file with `Args` and `run`.

#[cfg(feature = "bench")]
pub mod bench;
#[cfg(feature = "bench")]
mod bench_upload;
pub mod healthcheck;
pub mod info;
pub mod plan;
mod progress;
pub mod serve;
pub mod simulate;

/// An error and its causes in one line, as `{:#}` joins them, but without a cause whose text
/// the message already ends with: many of the library's errors show their source in their own
/// text as well as returning it, and the chain would say it twice.
pub fn describe(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if line.is_empty() {
            line = text;
        } else if !line.ends_with(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::describe;
    use asbuilt_plan::io::ReadError;

    #[test]
    fn each_cause_is_said_once() {
        // The read error shows its source in its text and returns it as its source too.
        let read = ReadError::Io {
            path: "scan.ply".into(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        };
        let e = anyhow::Error::new(read).context("planning");
        assert_eq!(describe(&e), "planning: scan.ply: no such file");
        // A cause the text does not show yet is still added.
        let e = anyhow::Error::new(std::io::Error::other("disk full")).context("writing plan.svg");
        assert_eq!(describe(&e), "writing plan.svg: disk full");
        assert_eq!(describe(&anyhow::anyhow!("alone")), "alone");
    }
}
