//! The room schedule as CSV (RFC 4180): one row per room, for spreadsheets and FM systems.
//!
//! Columns: `level`, `room`, `area_m2`, `perimeter_m`, `height_m`, `floor_z`, `ceiling_z`
//! (world heights), `neighbours` (room ids joined by a door or opening, space-separated).
//! Lines end in CRLF as the RFC says; a field holding a comma, quote or line break is quoted.
//! A value that is not a finite number is left empty rather than written as `NaN`.

use std::fmt::Write;

use crate::plan::FloorPlan;

/// The header row's fields.
pub const COLUMNS: [&str; 8] = [
    "level",
    "room",
    "area_m2",
    "perimeter_m",
    "height_m",
    "floor_z",
    "ceiling_z",
    "neighbours",
];

/// The schedule of every room of every story, stories in order.
pub fn to_csv(plan: &FloorPlan) -> String {
    let mut out = String::new();
    row(&mut out, COLUMNS.iter().map(|c| c.to_string()));
    let z0 = plan.origin[2];
    for story in &plan.stories {
        for room in &story.spaces.rooms {
            row(
                &mut out,
                [
                    story.level.to_string(),
                    room.id.clone(),
                    number(room.area, 2),
                    number(room.perimeter, 2),
                    number(room.ceiling_z - room.floor_z, 3),
                    number(room.floor_z + z0, 3),
                    number(room.ceiling_z + z0, 3),
                    room.neighbours.join(" "),
                ],
            );
        }
    }
    out
}

/// `v` with `decimals` places; empty when not finite.
fn number(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        String::new()
    }
}

fn row(out: &mut String, fields: impl IntoIterator<Item = String>) {
    for (i, f) in fields.into_iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push_str(&quote(&f));
    }
    out.push_str("\r\n");
}

/// A field as RFC 4180 wants it: quoted, with quotes doubled, when it needs to be.
fn quote(field: &str) -> String {
    if field.contains([',', '"', '\r', '\n']) {
        let mut q = String::with_capacity(field.len() + 2);
        let _ = write!(q, "\"{}\"", field.replace('"', "\"\""));
        q
    } else {
        field.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::geojson::tests::spaces_plan;

    /// Parses RFC 4180 text the long way, independently of the writer.
    fn parse(text: &str) -> Vec<Vec<String>> {
        let mut rows = vec![];
        let mut row = vec![];
        let mut field = String::new();
        let mut chars = text.chars().peekable();
        let mut quoted = false;
        while let Some(c) = chars.next() {
            match (quoted, c) {
                (true, '"') if chars.peek() == Some(&'"') => {
                    chars.next();
                    field.push('"');
                }
                (true, '"') => quoted = false,
                (true, c) => field.push(c),
                (false, '"') => quoted = true,
                (false, ',') => row.push(std::mem::take(&mut field)),
                (false, '\r') => assert_eq!(chars.next(), Some('\n'), "CR without LF"),
                (false, '\n') => panic!("bare LF ends a line"),
                (false, c) => field.push(c),
            }
            if !quoted && c == '\r' {
                row.push(std::mem::take(&mut field));
                rows.push(std::mem::take(&mut row));
            }
        }
        assert!(field.is_empty() && row.is_empty(), "last line not ended");
        rows
    }

    #[test]
    fn one_row_per_room_with_a_header() {
        let text = to_csv(&spaces_plan());
        let rows = parse(&text);
        assert_eq!(rows[0], COLUMNS);
        assert_eq!(rows.len(), 5);
        assert_eq!(
            rows[1],
            [
                "0",
                "L0-R1",
                "35.48",
                "25.48",
                "2.500",
                "100.000",
                "102.500",
                "L0-R2 L0-R3"
            ]
        );
        assert_eq!(rows[3][2], "9.65");
        assert_eq!(rows[3][4], "2.430");
        assert_eq!(rows[3][5], "100.020");
        assert_eq!(rows[4][0], "1");
        assert_eq!(rows[4][7], "");
        // The schedule's areas are the plan's.
        let total: f64 = rows[1..].iter().map(|r| r[2].parse::<f64>().unwrap()).sum();
        let want: f64 = spaces_plan()
            .stories
            .iter()
            .flat_map(|s| &s.spaces.rooms)
            .map(|r| r.area)
            .sum();
        assert!((total - want).abs() < 0.02);
    }

    #[test]
    fn awkward_fields_are_quoted_and_bad_numbers_left_empty() {
        let mut p = spaces_plan();
        let r = &mut p.stories[0].spaces.rooms[0];
        r.id = "hall, \"east\"\nwing".into();
        r.area = f64::NAN;
        let text = to_csv(&p);
        assert!(text.contains("\"hall, \"\"east\"\"\nwing\""));
        let rows = parse(&text);
        assert_eq!(rows.len(), 5);
        assert_eq!(rows[1][1], "hall, \"east\"\nwing");
        assert_eq!(rows[1][2], "");
        assert!(rows.iter().all(|r| r.len() == COLUMNS.len()));
    }

    #[test]
    fn a_plan_without_rooms_is_just_the_header() {
        let text = to_csv(&crate::io::geojson::tests::plan([0.0; 3], vec![]));
        assert_eq!(text, format!("{}\r\n", COLUMNS.join(",")));
    }
}
