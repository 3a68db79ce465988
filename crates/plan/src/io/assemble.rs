//! Building the compact `PointCloud` point by point as a reader decodes its chunks, so no reader
//! ever holds a second copy of the cloud.

use std::collections::HashMap;

use crate::cloud::{local_origin, to_local, PointCloud};

/// The most scans a cloud may name: scan slots are `u16`.
pub const MAX_SCANS: usize = u16::MAX as usize + 1;

/// Collects points into a [`PointCloud`]: local `f32` coordinates, scan slots, optional times.
/// Non-finite points are skipped and counted.
pub(crate) struct CloudBuilder {
    cloud: PointCloud,
    origin: Option<[f64; 3]>,
    skipped: u64,
    slot_of: HashMap<u32, u16>,
    last: Option<(u32, u16)>,
    keep_time: bool,
}

impl CloudBuilder {
    /// A builder expecting about `expected` points. `origin` fixes the local frame (from a
    /// header); otherwise the first finite point chooses it.
    pub fn new(format: &str, expected: usize, origin: Option<[f64; 3]>, keep_time: bool) -> Self {
        let mut cloud = PointCloud::default();
        cloud.source.format = format.into();
        // Exact reservations keep the peak at one array; growth beyond is left to `Vec`.
        cloud.xyz.reserve_exact(expected);
        CloudBuilder {
            cloud,
            origin: origin.map(|o| local_origin(Some(o))),
            skipped: 0,
            slot_of: HashMap::new(),
            last: None,
            keep_time,
        }
    }

    /// Makes room for `n` more points.
    pub fn reserve(&mut self, n: usize) {
        self.cloud.xyz.reserve_exact(n);
    }

    /// Declares a scan before its points (E57 declares every scan, even empty ones).
    pub fn scan_slot(&mut self, id: u32) -> Result<u16, String> {
        if let Some((last_id, slot)) = self.last {
            if last_id == id {
                return Ok(slot);
            }
        }
        let slot = match self.slot_of.get(&id) {
            Some(&slot) => slot,
            None => {
                let n = self.cloud.scan_ids.len();
                if n >= MAX_SCANS {
                    return Err(format!("more than {MAX_SCANS} distinct scan indices"));
                }
                self.cloud.scan_ids.push(id);
                self.slot_of.insert(id, n as u16);
                n as u16
            }
        };
        self.last = Some((id, slot));
        Ok(slot)
    }

    /// Adds a point in world coordinates. `scan` is a slot from [`Self::scan_slot`].
    #[inline]
    pub fn push(&mut self, p: [f64; 3], scan: Option<u16>, time: Option<f64>) {
        if !(p[0].is_finite() && p[1].is_finite() && p[2].is_finite()) {
            self.skipped += 1;
            return;
        }
        let origin = *self.origin.get_or_insert_with(|| local_origin(Some(p)));
        if self.cloud.xyz.len() == self.cloud.xyz.capacity() {
            // Grow by a quarter, not double, so the array never overshoots by much.
            let extra = (self.cloud.xyz.len() / 4).max(1 << 16);
            self.cloud.xyz.reserve_exact(extra);
        }
        self.cloud.xyz.push(to_local(origin, p));
        if let Some(slot) = scan {
            if self.cloud.scan.capacity() == 0 {
                self.cloud.scan.reserve_exact(self.cloud.xyz.capacity());
            }
            self.cloud.scan.push(slot);
        }
        if let (true, Some(t)) = (self.keep_time, time) {
            if self.cloud.time.capacity() == 0 {
                self.cloud.time.reserve_exact(self.cloud.xyz.capacity());
            }
            self.cloud.time.push(t);
        }
    }

    /// True once a finite point has fixed the local frame.
    pub fn has_origin(&self) -> bool {
        self.origin.is_some()
    }

    /// The local frame's origin, once fixed.
    pub fn origin(&self) -> Option<[f64; 3]> {
        self.origin
    }

    /// Fixes the local frame from world point `p` (finite), as pushing it first would.
    pub fn fix_origin(&mut self, p: [f64; 3]) {
        self.origin.get_or_insert_with(|| local_origin(Some(p)));
    }

    /// Counts `n` points skipped as non-finite by a decoder that placed points itself.
    pub fn skip(&mut self, n: u64) {
        self.skipped += n;
    }

    /// An empty builder in this one's local frame, for a piece of the file decoded on another
    /// thread and appended with [`Self::absorb`]. Call it once the frame is fixed.
    pub fn part(&self, expected: usize) -> CloudBuilder {
        let mut part = CloudBuilder::new(&self.cloud.source.format, expected, None, self.keep_time);
        part.origin = self.origin;
        part
    }

    /// Appends a part's points as if they had been pushed here, in order: its scans take
    /// slots here in their order of first appearance, its skipped points add up. On error (too
    /// many scans) nothing of the part is added, though its first scans may have slots.
    pub fn absorb(&mut self, part: &CloudBuilder) -> Result<(), String> {
        let slots = part
            .cloud
            .scan_ids
            .iter()
            .map(|&id| self.scan_slot(id))
            .collect::<Result<Vec<u16>, String>>()?;
        let (from, c) = (&part.cloud, &mut self.cloud);
        let n = from.xyz.len();
        if c.xyz.capacity() - c.xyz.len() < n {
            // As `push` grows: by a quarter, never doubling.
            c.xyz.reserve_exact(n.max(c.xyz.len() / 4).max(1 << 16));
        }
        c.xyz.extend_from_slice(&from.xyz);
        if !from.scan.is_empty() {
            // Sized to the point array, so neither array doubles.
            c.scan.reserve_exact(c.xyz.capacity() - c.scan.len());
            c.scan
                .extend(from.scan.iter().map(|&s| slots[usize::from(s)]));
        }
        if !from.time.is_empty() {
            c.time.reserve_exact(c.xyz.capacity() - c.time.len());
            c.time.extend_from_slice(&from.time);
        }
        self.skipped += part.skipped;
        if self.origin.is_none() {
            self.origin = part.origin;
        }
        Ok(())
    }

    /// Gives access to the cloud's other fields (viewpoints, CRS, details) before finishing.
    pub fn cloud_mut(&mut self) -> &mut PointCloud {
        &mut self.cloud
    }

    /// The cloud so far without its points, as [`Self::finish`] would record it; for chunked
    /// reads, whose points are handed over as they come.
    pub fn skeleton(&self, details: String) -> PointCloud {
        let c = &self.cloud;
        let mut out = PointCloud {
            origin: self.origin.unwrap_or([0.0; 3]),
            scan_ids: c.scan_ids.clone(),
            viewpoints: c.viewpoints.clone(),
            crs: c.crs.clone(),
            source: c.source.clone(),
            ..Default::default()
        };
        out.source.details = details;
        out.source.skipped += self.skipped;
        if out.source.skipped > 0 && out.source.skipped_reason.is_none() {
            out.source.skipped_reason = Some("non-finite coordinates".into());
        }
        out
    }

    /// Finishes the cloud: trims spare capacity and records what was skipped.
    pub fn finish(mut self, details: String) -> PointCloud {
        let c = &mut self.cloud;
        c.origin = self.origin.unwrap_or([0.0; 3]);
        c.xyz.shrink_to_fit();
        c.scan.shrink_to_fit();
        c.time.shrink_to_fit();
        // A scan index per point is only meaningful when every point has one.
        if c.scan.len() != c.xyz.len() {
            c.scan.clear();
        }
        if c.time.len() != c.xyz.len() {
            c.time = Vec::new();
        }
        if c.scan.is_empty() && !matches!(c.viewpoints, crate::cloud::Viewpoints::Static(_)) {
            c.scan_ids.clear();
        }
        c.source.details = details;
        c.source.skipped += self.skipped;
        if c.source.skipped > 0 && c.source.skipped_reason.is_none() {
            c.source.skipped_reason = Some("non-finite coordinates".into());
        }
        self.cloud
    }
}

/// Scan slots of one piece of a file decoded on a thread of its own, in order of first
/// appearance there; merged into the cloud's slots once every earlier piece is in.
pub(crate) struct LocalSlots {
    pub ids: Vec<u32>,
    map: HashMap<u32, u16>,
    last: Option<(u32, u16)>,
}

impl LocalSlots {
    pub fn new() -> Self {
        LocalSlots {
            ids: Vec::new(),
            map: HashMap::new(),
            last: None,
        }
    }

    /// The local slot of scan `id`; `None` once the piece names more scans than slots hold.
    #[inline(always)]
    pub fn slot(&mut self, id: u32) -> Option<u16> {
        // Scans come in runs: the last one answers almost every point.
        match self.last {
            Some((last_id, slot)) if last_id == id => Some(slot),
            _ => self.look_up(id),
        }
    }

    #[inline(never)]
    fn look_up(&mut self, id: u32) -> Option<u16> {
        let slot = match self.map.get(&id) {
            Some(&slot) => slot,
            None => {
                let n = self.ids.len();
                if n >= MAX_SCANS {
                    return None;
                }
                self.ids.push(id);
                self.map.insert(id, n as u16);
                n as u16
            }
        };
        self.last = Some((id, slot));
        Some(slot)
    }
}

/// One piece's stretch of the cloud's arrays. `scan` and `time` are empty when the cloud has
/// none.
pub(crate) struct Out<'a> {
    pub xyz: &'a mut [[f32; 3]],
    pub scan: &'a mut [u16],
    pub time: &'a mut [f64],
}

impl<'a> Out<'a> {
    /// Points `at..at + n` of the cloud's arrays.
    pub fn of(c: &'a mut PointCloud, at: usize, n: usize) -> Out<'a> {
        let part = |len: usize| if len == 0 { 0..0 } else { at..at + n };
        let (scan, time) = (part(c.scan.len()), part(c.time.len()));
        Out {
            xyz: &mut c.xyz[at..at + n],
            scan: &mut c.scan[scan],
            time: &mut c.time[time],
        }
    }
}

/// Cuts the arrays (`scan` and `time` as long as `xyz`, or empty) into pieces of `per` points,
/// the last one shorter.
pub(crate) fn split_out<'a>(
    mut xyz: &'a mut [[f32; 3]],
    mut scan: &'a mut [u16],
    mut time: &'a mut [f64],
    per: usize,
) -> Vec<Out<'a>> {
    let per = per.max(1);
    let mut outs = Vec::with_capacity(xyz.len().div_ceil(per));
    while !xyz.is_empty() {
        let n = per.min(xyz.len());
        outs.push(Out {
            xyz: take_front(&mut xyz, n),
            scan: take_front(&mut scan, n),
            time: take_front(&mut time, n),
        });
    }
    outs
}

/// Decodes the fixed-size records `buf` (`size` bytes each) into `out` with `decode`, in pieces
/// of `per` records on the pool's threads (one piece when they all fit), in order.
pub(crate) fn decode_pieces<P: Send>(
    out: Out<'_>,
    buf: &[u8],
    size: usize,
    per: usize,
    decode: impl Fn(&[u8], Out<'_>) -> P + Sync,
) -> Vec<P> {
    use rayon::prelude::*;
    if out.xyz.len() <= per {
        return vec![decode(buf, out)];
    }
    split_out(out.xyz, out.scan, out.time, per)
        .into_par_iter()
        .zip(buf.par_chunks(per * size))
        .map(|(out, recs)| decode(recs, out))
        .collect()
}

/// The first `n` items of `a` (all of them when fewer), leaving `a` the rest.
fn take_front<'a, T>(a: &mut &'a mut [T], n: usize) -> &'a mut [T] {
    let k = n.min(a.len());
    let (head, rest) = std::mem::take(a).split_at_mut(k);
    *a = rest;
    head
}

/// After pieces of `per` points each wrote their `kept` points at the start of their stretch,
/// renumbers each piece's scan slots with its `map` (local slot -> cloud slot) and closes the
/// gaps skipped points left. Returns the points kept in all.
pub(crate) fn settle(out: Out<'_>, per: usize, pieces: &[(usize, Vec<u16>)]) -> usize {
    use rayon::prelude::*;
    let identity = |map: &[u16]| map.iter().enumerate().all(|(i, &s)| usize::from(s) == i);
    if !out.scan.is_empty() && pieces.iter().any(|(_, map)| !identity(map)) {
        out.scan
            .par_chunks_mut(per.max(1))
            .zip(pieces.par_iter())
            .for_each(|(scan, (kept, map))| {
                for s in &mut scan[..*kept] {
                    *s = map[usize::from(*s)];
                }
            });
    }
    let mut to = 0;
    for (k, (kept, _)) in pieces.iter().enumerate() {
        let from = k * per;
        if from != to {
            // Only where points were skipped: rare, so a serial move is fine.
            out.xyz.copy_within(from..from + kept, to);
            if !out.scan.is_empty() {
                out.scan.copy_within(from..from + kept, to);
            }
            if !out.time.is_empty() {
                out.time.copy_within(from..from + kept, to);
            }
        }
        to += kept;
    }
    to
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skips_non_finite_points_and_counts_them() {
        let mut b = CloudBuilder::new("xyz", 4, None, true);
        let s = b.scan_slot(7).unwrap();
        b.push([1.0, 2.0, 3.0], Some(s), Some(0.5));
        b.push([f64::NAN, 2.0, 3.0], Some(s), Some(0.6));
        b.push([1.0, f64::INFINITY, 3.0], Some(s), Some(0.7));
        let c = b.finish("test".into());
        assert_eq!(c.xyz, vec![[1.0, 2.0, 3.0]]);
        assert_eq!(c.source.skipped, 2);
        assert_eq!(
            c.source.skipped_reason.as_deref(),
            Some("non-finite coordinates")
        );
        assert_eq!(c.scan, vec![0]);
        assert_eq!(c.time, vec![0.5]);
        assert!(c.check().is_ok());
    }

    #[test]
    fn far_points_get_a_kilometre_origin_and_scans_get_slots_in_order() {
        let mut b = CloudBuilder::new("las", 0, None, false);
        let a = b.scan_slot(16).unwrap();
        let c = b.scan_slot(3).unwrap();
        assert_eq!((a, c, b.scan_slot(16).unwrap()), (0, 1, 0));
        b.push([500_123.5, 5_400_321.25, 12.0], Some(a), Some(1.0));
        b.push([500_124.5, 5_400_322.25, 13.0], Some(c), Some(2.0));
        let cloud = b.finish(String::new());
        assert_eq!(cloud.origin, [500_000.0, 5_400_000.0, 0.0]);
        assert_eq!(cloud.xyz[1], [124.5, 322.25, 13.0]);
        assert_eq!(cloud.scan_ids, vec![16, 3]);
        assert_eq!(cloud.scan, vec![0, 1]);
        assert!(cloud.time.is_empty(), "times are dropped unless kept");
    }
}
