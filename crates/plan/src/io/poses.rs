//! The pose sidecars of `shared/design/contract.md` §2: static scan poses and mobile trajectories.
