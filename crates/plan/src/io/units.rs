//! Catching clouds in the wrong units before they become nonsense plans.

use crate::cloud::PointCloud;

/// Taller than this (in the cloud's units) is no building interior in metres.
pub const MAX_HEIGHT_M: f64 = 150.0;

/// A cloud whose size says its units are not metres.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnitsError {
    /// The cloud is far taller than a building interior in metres.
    #[error(
        "the cloud is {height:.0} units tall, far more than a building interior in metres; \
         it is probably in {unit}: pass --scale {scale} (the scale option) to convert it"
    )]
    NotMetres {
        /// The cloud's height, in its own units.
        height: f64,
        /// The unit it is probably in.
        unit: &'static str,
        /// The scale that converts it to metres.
        scale: f64,
    },
}

/// Checks that the cloud's height is plausible in metres. A story scanned in millimetres is
/// about 2,700 units tall; in centimetres, about 270. The height is taken between the 0.1 % and
/// 99.9 % quantiles of z, so a few stray points do not trigger it.
pub fn check_units(cloud: &PointCloud) -> Result<(), UnitsError> {
    let height = robust_height(cloud);
    if height <= MAX_HEIGHT_M {
        return Ok(());
    }
    let (unit, scale) = if height > 1500.0 {
        ("millimetres", 0.001)
    } else {
        ("centimetres", 0.01)
    };
    Err(UnitsError::NotMetres {
        height,
        unit,
        scale,
    })
}

/// The z extent between the 0.1 % and 99.9 % quantiles of an even subsample.
fn robust_height(cloud: &PointCloud) -> f64 {
    const SAMPLE: usize = 100_000;
    let n = cloud.xyz.len();
    if n == 0 {
        return 0.0;
    }
    let step = n.div_ceil(SAMPLE);
    let mut z: Vec<f32> = cloud.xyz.iter().step_by(step).map(|p| p[2]).collect();
    z.sort_unstable_by(f32::total_cmp);
    let at = |q: f64| z[((z.len() - 1) as f64 * q).round() as usize];
    f64::from(at(0.999)) - f64::from(at(0.001))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn story(height: f64) -> PointCloud {
        let pts: Vec<[f64; 3]> = (0..1000)
            .map(|i| {
                let t = i as f64 / 999.0;
                [t * 4.0 * height, (1.0 - t) * 3.0 * height, t * height]
            })
            .collect();
        PointCloud::from_world(&pts)
    }

    #[test]
    fn a_story_in_metres_passes() {
        assert_eq!(check_units(&story(2.7)), Ok(()));
        assert_eq!(check_units(&PointCloud::default()), Ok(()));
    }

    #[test]
    fn a_story_in_millimetres_suggests_the_scale() {
        let err = check_units(&story(2700.0)).unwrap_err();
        let text = err.to_string();
        // The quantiles trim 0.1 % at each end: 2,695 of the 2,700.
        assert!(
            text.contains("2695 units tall") && text.contains("millimetres"),
            "{text}"
        );
        assert!(text.contains("--scale 0.001"), "{text}");
        let err = check_units(&story(270.0)).unwrap_err();
        assert!(err.to_string().contains("--scale 0.01"), "{err}");
    }

    #[test]
    fn stray_points_do_not_count() {
        let mut c = story(2.7);
        c.xyz[10][2] = 5000.0;
        assert_eq!(check_units(&c), Ok(()));
    }
}
