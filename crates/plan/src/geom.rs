//! Small 2D geometry helpers shared by the stages. Points are `[f64; 2]` in the local frame.

/// A 2D point or vector.
pub type P2 = [f64; 2];

/// `a - b`.
pub fn sub(a: P2, b: P2) -> P2 {
    [a[0] - b[0], a[1] - b[1]]
}

/// `a + b`.
pub fn add(a: P2, b: P2) -> P2 {
    [a[0] + b[0], a[1] + b[1]]
}

/// `a` scaled by `s`.
pub fn scale(a: P2, s: f64) -> P2 {
    [a[0] * s, a[1] * s]
}

/// The dot product.
pub fn dot(a: P2, b: P2) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// The z component of the 3D cross product.
pub fn cross(a: P2, b: P2) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// The Euclidean length.
pub fn norm(a: P2) -> f64 {
    a[0].hypot(a[1])
}

/// The Euclidean distance between two points.
pub fn dist(a: P2, b: P2) -> f64 {
    norm(sub(a, b))
}

/// Unit vector along `a`, or `None` for a zero vector.
pub fn normalize(a: P2) -> Option<P2> {
    let n = norm(a);
    (n > 0.0 && n.is_finite()).then(|| scale(a, 1.0 / n))
}

/// Signed area of a closed ring given without its repeated last point; CCW is positive.
pub fn ring_signed_area(ring: &[P2]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| cross(ring[i], ring[(i + 1) % n]))
        .sum::<f64>()
        / 2.0
}

/// A ring closed by repeating its first position, with consecutive repeats dropped (a ring
/// given closed is not closed twice). `None` when fewer than three positions remain.
pub fn closed_ring(points: impl IntoIterator<Item = P2>) -> Option<Vec<P2>> {
    let points = points.into_iter();
    let mut out: Vec<P2> = Vec::with_capacity(points.size_hint().0 + 1);
    for p in points {
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    if out.len() < 3 {
        return None;
    }
    out.push(out[0]);
    Some(out)
}

/// Distance from `p` to the segment `a`–`b`.
pub fn point_segment_distance(p: P2, a: P2, b: P2) -> f64 {
    let ab = sub(b, a);
    let len2 = dot(ab, ab);
    let t = if len2 > 0.0 {
        (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist(p, add(a, scale(ab, t)))
}

/// Even-odd point in ring.
pub fn point_in_ring(p: P2, ring: &[P2]) -> bool {
    let n = ring.len();
    let mut inside = false;
    for k in 0..n {
        let (a, b) = (ring[k], ring[(k + 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_square_area_is_one_and_ccw_positive() {
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert_eq!(ring_signed_area(&sq), 1.0);
        let mut cw = sq;
        cw.reverse();
        assert_eq!(ring_signed_area(&cw), -1.0);
    }

    #[test]
    fn closed_ring_drops_repeats_and_closes_once() {
        let sq = [
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [0.0, 0.0],
        ];
        let ring = closed_ring(sq).unwrap();
        assert_eq!(ring.len(), 5);
        assert_eq!(ring.first(), ring.last());
        assert_eq!(ring[1], [1.0, 0.0]);
        assert_eq!(ring[2], [1.0, 1.0]);
        // Two distinct positions are no ring.
        assert!(closed_ring([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]).is_none());
    }

    #[test]
    fn segment_distance_clamps_to_endpoints() {
        assert_eq!(
            point_segment_distance([2.0, 0.0], [0.0, 0.0], [1.0, 0.0]),
            1.0
        );
        assert_eq!(
            point_segment_distance([0.5, 2.0], [0.0, 0.0], [1.0, 0.0]),
            2.0
        );
    }
}
