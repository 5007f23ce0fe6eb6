//! diag-bench: an independent test-data generator and black-box scorer for the joint's
//! "sim-to-real gap diagnosis" (`jointctl diagnose`, spec §3 of `shared/spec/formats.md`).
//!
//! # Why it exists
//! A diagnosis tuned on data from its own simulator learns that simulator's habits. This
//! crate draws joints, trajectories, sensor chains and one withheld effect per case from
//! physics written here, from the papers' parameter magnitudes and the file-format spec
//! alone, writes the log (spec §1) and the model file the user would give (spec §2: the true
//! joint minus the withheld effect), and records the truth beside them. `diag-bench run`
//! then runs the tool as a child process and scores its verdicts.
//!
//! # Independence rule
//! This crate must never share code with the diagnosis (`host-sim/src/diagnose/`), the
//! simulator's plant and effects (`host-sim/src/plant.rs`, `effects.rs`, `sim.rs`) or read
//! the diagnosis docs: it depends on no crate of this workspace, only on crates.io crates
//! (rand, rand_chacha, rand_distr, serde, serde_json, toml, clap, anyhow). Every effect's
//! maths is written here in f64. A shared bug would otherwise be invisible to the score.
//!
//! # Seeds
//! Development seeds 1–20 may be looked at while developing the diagnosis. Seeds 9001–9010
//! are the "unseen" seeds: they are reported separately (`seed_class` in the manifest and in
//! the scorer's tables) and are never used to tune anything, the diagnosis or this
//! generator. The generator itself is not tuned to the tool's current answers either.
//!
//! # Layout
//! - [`rngs`]: per-(seed, case) random streams and draws;
//! - [`model`]: the model file (spec §2) and the torque its terms state;
//! - [`joint`]: the joint draws (trunk, arm, elastic, pendulum);
//! - [`traj`]: prescribed trajectories with exact derivatives (torque mode);
//! - [`effects`]: the withheld effects and their torques;
//! - [`noise`]: sensor noise, quantisation, filters;
//! - [`shown`]: what the log must show of an effect for its label to hold;
//! - [`torque`], [`trajmode`], [`integrate`]: the two modes;
//! - [`case`], [`gen`]: a case's files and the `gen` command;
//! - [`score`]: the `run` command.

pub mod case;
pub mod effects;
pub mod gen;
pub mod integrate;
pub mod joint;
pub mod model;
pub mod noise;
pub mod rngs;
pub mod score;
pub mod shown;
pub mod torque;
pub mod traj;
pub mod trajmode;
