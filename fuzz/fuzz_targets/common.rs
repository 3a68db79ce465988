//! Shared by the targets: read `data` as one format through the library's in-memory entry point.

use asbuilt_plan::io::{self, Format, ReadOptions};

/// Reads the bytes as `format`. Errors are the expected outcome; a panic, hang or huge
/// allocation is a finding. (The reader thread turns panics into errors, but libFuzzer's panic
/// hook aborts first, so panics are still reported.)
pub fn read(data: &[u8], format: Format, scan_column: Option<usize>) {
    // Half the inputs are read without times (as for a posed scan), so both layouts are tried.
    let options = ReadOptions {
        format: Some(format),
        scan_column,
        keep_time: data.len() % 2 == 0,
        ..Default::default()
    };
    let name = format!("fuzz.{format}");
    if let Ok(cloud) = io::read_cloud_from(std::io::Cursor::new(data.to_vec()), &name, &options) {
        assert!(cloud.check().is_ok());
        assert!(cloud.len() as u64 <= data.len() as u64 * 64);
    }
}
