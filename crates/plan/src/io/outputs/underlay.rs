//! `underlay.png`: every story's underlay ([`crate::underlay`]) in one indexed PNG, stories
//! stacked from level 0 at the top, north up, one pixel per grid cell. Where each story lies,
//! in the image and in the plan's coordinates, is `floorplan.underlay` in the GeoJSON
//! ([`describe`]). Transparent where no point fell, so the plan shows through.

use serde_json::{json, Value};

use crate::plan::FloorPlan;
use crate::underlay::Underlay;

/// The file name, as listed in `io::outputs::OUTPUTS`.
pub(crate) const FILE: &str = "underlay.png";

/// One story's place in the image: its rectangle's top row (its left column is 0).
struct Placed<'a> {
    level: usize,
    underlay: &'a Underlay,
    top: usize,
}

/// The stories with an underlay, stacked, and the image's width and height.
fn layout(plan: &FloorPlan) -> (Vec<Placed<'_>>, usize, usize) {
    let mut placed = Vec::new();
    let (mut w, mut h) = (0, 0);
    for s in &plan.stories {
        if let Some(u) = &s.underlay {
            placed.push(Placed {
                level: s.level,
                underlay: u,
                top: h,
            });
            w = w.max(u.nx);
            h += u.ny;
        }
    }
    (placed, w, h)
}

/// The image: every story's underlay, or a single transparent pixel when no story has one
/// (`floorplan.underlay` is then `null`).
pub(crate) fn to_png(plan: &FloorPlan) -> Result<Vec<u8>, String> {
    let (placed, w, h) = layout(plan);
    if placed.is_empty() {
        return encode(1, 1, &[0]);
    }
    let mut pixels = vec![0u8; w * h];
    for p in &placed {
        copy_rows(p.underlay, &mut pixels[p.top * w..], w);
    }
    encode(w, h, &pixels)
}

/// One story's underlay alone, for the SVG.
pub(crate) fn story_png(u: &Underlay) -> Result<Vec<u8>, String> {
    let mut pixels = vec![0u8; u.nx * u.ny];
    copy_rows(u, &mut pixels, u.nx);
    encode(u.nx, u.ny, &pixels)
}

/// Writes `u`'s rows into `out` (rows of `width` pixels), north first.
fn copy_rows(u: &Underlay, out: &mut [u8], width: usize) {
    for row in 0..u.ny {
        let j = u.ny - 1 - row;
        out[row * width..row * width + u.nx].copy_from_slice(&u.levels[j * u.nx..(j + 1) * u.nx]);
    }
}

/// The colour of each level: 0 transparent; 1 a pale wash (points off the slice); 2..=255 ink
/// growing darker and more opaque with the slice's density.
fn palette() -> (Vec<u8>, Vec<u8>) {
    let mut rgb = vec![0, 0, 0, 96, 118, 150];
    let mut alpha = vec![0, 56];
    for level in 2..=255u32 {
        let t = (level - 2) as f64 / 253.0;
        let mix = |a: f64, b: f64| (a + (b - a) * t).round() as u8;
        rgb.extend([mix(70.0, 12.0), mix(84.0, 18.0), mix(120.0, 40.0)]);
        alpha.push(mix(90.0, 255.0));
    }
    (rgb, alpha)
}

fn encode(w: usize, h: usize, pixels: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, w as u32, h as u32);
    let (rgb, alpha) = palette();
    encoder.set_color(png::ColorType::Indexed);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_palette(rgb);
    encoder.set_trns(alpha);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder
        .write_header()
        .map_err(|e| format!("underlay PNG: {e}"))?;
    writer
        .write_image_data(pixels)
        .map_err(|e| format!("underlay PNG: {e}"))?;
    writer.finish().map_err(|e| format!("underlay PNG: {e}"))?;
    Ok(out)
}

/// `floorplan.underlay`: the image's file and size, and per story its rectangle in the image
/// (`pixels`: left, top, width, height) and in the plan's coordinates (`bbox`: west, south,
/// east, north, like the features'), its cell size, the slice's world heights, and the slice
/// points per cell drawn at full ink. `null` when no story has an underlay.
pub(crate) fn describe(plan: &FloorPlan) -> Value {
    let (placed, w, h) = layout(plan);
    if placed.is_empty() {
        return Value::Null;
    }
    let o = plan.origin;
    let r4 = |v: f64| (v * 1e4).round() / 1e4;
    let stories: Vec<Value> = placed
        .iter()
        .map(|p| {
            let u = p.underlay;
            let [lo, hi] = u.bounds();
            json!({
                "level": p.level,
                "pixels": [0, p.top, u.nx, u.ny],
                "bbox": [r4(lo[0] + o[0]), r4(lo[1] + o[1]), r4(hi[0] + o[0]), r4(hi[1] + o[1])],
                "cell_m": r4(u.cell),
                "slice_z": u.slice_z.map(|z| r4(z + o[2])),
                "full_count": u.full,
            })
        })
        .collect();
    json!({
        "file": FILE,
        "size": [w, h],
        "what": "points per grid cell in a slice at mid-height (slice_z), darker with more; pale where the story has points only above or below it",
        "stories": stories,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn underlay(nx: usize, ny: usize, levels: Vec<u8>) -> Underlay {
        Underlay {
            origin: [1.0, 2.0],
            cell: 0.05,
            nx,
            ny,
            slice_z: [1.0, 1.5],
            levels,
            full: 40,
        }
    }

    /// Decodes with the `png` crate's own decoder: the indices, rows north first.
    fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>, Vec<u8>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        let trns = reader.info().trns.as_ref().unwrap().to_vec();
        (info.width, info.height, buf, trns)
    }

    #[test]
    fn stories_stack_north_up_and_the_geojson_says_where() {
        let mut plan = crate::io::geojson::tests::plan(
            [100.0, 200.0, 10.0],
            vec![
                crate::io::geojson::tests::story(0, vec![], vec![]),
                crate::io::geojson::tests::story(1, vec![], vec![]),
            ],
        );
        // Level 0: 3 × 2, its south-west cell dark; level 1: 2 × 1.
        plan.stories[0].underlay = Some(underlay(3, 2, vec![255, 1, 0, 0, 0, 2]));
        plan.stories[1].underlay = Some(underlay(2, 1, vec![1, 1]));
        let (w, h, px, trns) = decode(&to_png(&plan).unwrap());
        assert_eq!((w, h), (3, 3));
        // Row 0 is level 0's north row; level 1 below, padded with transparency.
        assert_eq!(px, vec![0, 0, 2, 255, 1, 0, 1, 1, 0]);
        assert_eq!((trns[0], trns[255]), (0, 255));
        let d = describe(&plan);
        assert_eq!(d["file"], "underlay.png");
        assert_eq!(d["size"], json!([3, 3]));
        let s1 = &d["stories"][1];
        assert_eq!(s1["level"], 1);
        assert_eq!(s1["pixels"], json!([0, 2, 2, 1]));
        assert_eq!(s1["bbox"], json!([101.0, 202.0, 101.1, 202.05]));
        assert_eq!(s1["slice_z"], json!([11.0, 11.5]));
        // One story alone, for the SVG.
        let (w, h, px, _) = decode(&story_png(plan.stories[0].underlay.as_ref().unwrap()).unwrap());
        assert_eq!((w, h, px), (3, 2, vec![0, 0, 2, 255, 1, 0]));
    }

    #[test]
    fn a_plan_without_underlays_gives_one_clear_pixel_and_null() {
        let plan = crate::io::geojson::tests::plan([0.0; 3], vec![]);
        let (w, h, px, trns) = decode(&to_png(&plan).unwrap());
        assert_eq!((w, h, px[0], trns[0]), (1, 1, 0, 0));
        assert_eq!(describe(&plan), Value::Null);
    }
}
