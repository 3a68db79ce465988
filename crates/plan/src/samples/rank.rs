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
