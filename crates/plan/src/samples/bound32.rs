//! Bounds given in f64 as f32 ones that compare the same. The points are f32; a test such as
//! `p as f64 >= lo` then needs no widening of each point, and runs on four f32 lanes at a time.

/// The least `f32` at or above `v`: for every `f32` z, `z as f64 >= v` exactly when
/// `z >= least_at_or_above(v)` (both false for NaN), and `z as f64 < v` exactly when
/// `z < least_at_or_above(v)`.
pub(super) fn least_at_or_above(v: f64) -> f32 {
    if v.is_nan() {
        return f32::NAN;
    }
    // The nearest f32, then a step up when it lies below `v`, or down while the one below
    // still does not.
    let mut c = v as f32;
    if (c as f64) < v {
        c = c.next_up();
    }
    while c > f32::NEG_INFINITY && (c.next_down() as f64) >= v {
        c = c.next_down();
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_least_f32_at_or_above_compares_as_the_f64_does() {
        let vs = [
            0.0,
            -0.0,
            0.1,
            -0.1,
            0.5,
            2.7,
            -1.75,
            1e-40,
            // Halfway between two f32s, and just either side of that.
            1.0 + f64::from(f32::EPSILON) / 2.0,
            1.0 + f64::from(f32::EPSILON) / 2.0 + 1e-12,
            1.0 + f64::from(f32::EPSILON) / 2.0 - 1e-12,
            f64::from(f32::MAX) * 1.5,
            -f64::from(f32::MAX) * 1.5,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for v in vs {
            let c = least_at_or_above(v);
            assert!(c as f64 >= v, "{v}: {c}");
            for z in [
                c.next_down().next_down(),
                c.next_down(),
                c,
                c.next_up(),
                0.0,
                -0.0,
            ] {
                assert_eq!(z as f64 >= v, z >= c, "{v}: {z} against {c}");
                assert_eq!((z as f64) < v, z < c, "{v}: {z} against {c}");
            }
        }
        // Exact values are their own bound. 0.1 and -0.1 lie between two f32s: the nearest
        // one is above 0.1 but below -0.1, where the next one up is the bound.
        assert_eq!(least_at_or_above(0.5), 0.5);
        assert_eq!(least_at_or_above(0.1), 0.1f32);
        assert_eq!(least_at_or_above(-0.1), (-0.1f32).next_up());
        assert!(least_at_or_above(f64::NAN).is_nan());
    }
}
