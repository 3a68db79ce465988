//! Selecting the value of a given rank among coordinates, in `f32::total_cmp`'s order. The
//! medians select from a few hundred coordinates per cell; comparing integers keys costs less
//! than `total_cmp`, which turns both of its operands into such keys at every comparison.

/// The key of `v` whose integer order is `f32::total_cmp`'s: the bits, with those below the
/// sign flipped for negative values (as `total_cmp` does).
#[inline]
pub(super) fn key(v: f32) -> i32 {
    let bits = v.to_bits() as i32;
    bits ^ (((bits >> 31) as u32) >> 1) as i32
}

/// The value whose [`key`] is `k`: the flip leaves the sign bit alone, so it undoes itself.
#[inline]
pub(super) fn value(k: i32) -> f32 {
    f32::from_bits((k ^ (((k >> 31) as u32) >> 1) as i32) as u32)
}

/// The keys of the values of `vals` marked to be kept, in order, in the first entries of
/// `buf`, which are returned. Each key is written and the next place moved on only for a kept
/// value, so no branch depends on which values are kept; `buf` only grows, so it is not zeroed
/// again for every call.
pub(super) fn keys_where(
    buf: &mut Vec<i32>,
    vals: impl ExactSizeIterator<Item = (f32, bool)>,
) -> &mut [i32] {
    if buf.len() < vals.len() {
        buf.resize(vals.len(), 0);
    }
    let mut at = 0;
    for (v, keep) in vals {
        buf[at] = key(v);
        at += usize::from(keep);
    }
    &mut buf[..at]
}

/// The value of rank `n` (from 0) among the values whose keys are `keys`, in total order;
/// `keys` is reordered.
pub(super) fn nth(keys: &mut [i32], n: usize) -> f32 {
    value(*keys.select_nth_unstable(n).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_order_values_as_total_cmp_does_and_give_them_back() {
        let vals = [
            f32::NEG_INFINITY,
            -1.5,
            -f32::MIN_POSITIVE,
            -0.0,
            0.0,
            f32::from_bits(1),
            0.05,
            0.050000004,
            3.0e7,
            f32::INFINITY,
        ];
        for a in vals {
            assert_eq!(value(key(a)).to_bits(), a.to_bits(), "{a}");
            for b in vals {
                assert_eq!(key(a).cmp(&key(b)), a.total_cmp(&b), "{a} {b}");
            }
        }
        // -0 sorts before +0, and each comes back with its sign.
        assert!(key(-0.0) < key(0.0));
        let mut keys: Vec<i32> = [0.0f32, -0.0, 0.0].iter().map(|&v| key(v)).collect();
        assert_eq!(nth(&mut keys, 0).to_bits(), (-0.0f32).to_bits());
    }

    #[test]
    fn the_kept_values_keys_come_first_in_order() {
        let mut buf = vec![7; 2];
        let vals = [
            (1.0f32, true),
            (2.0, false),
            (-3.0, true),
            (4.0, false),
            (5.0, true),
        ];
        let keys = keys_where(&mut buf, vals.iter().copied());
        assert_eq!(keys, &[key(1.0), key(-3.0), key(5.0)]);
        // A shorter call reuses the buffer without shrinking it.
        assert_eq!(
            keys_where(&mut buf, [(0.5f32, false)].into_iter()),
            &[] as &[i32]
        );
        assert_eq!(
            keys_where(&mut buf, [(0.5f32, true)].into_iter()),
            &[key(0.5)]
        );
        assert_eq!(buf.len(), 5);
    }

    #[test]
    fn the_nth_value_is_that_of_the_sorted_values() {
        let vals: Vec<f32> = (0..101u32)
            .map(|k| (k.wrapping_mul(2_654_435_761) % 1000) as f32 * 0.001 - 0.4)
            .collect();
        let mut sorted = vals.clone();
        sorted.sort_by(f32::total_cmp);
        for n in [0, 1, 50, 99, 100] {
            let mut keys: Vec<i32> = vals.iter().map(|&v| key(v)).collect();
            assert_eq!(nth(&mut keys, n), sorted[n], "rank {n}");
        }
    }
}
