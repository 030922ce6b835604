//! Refusals: every test of what the library does with input it must not take at face value —
//! malformed or hostile URDF and scene files, non-finite and absurd numbers, ill-posed
//! `kind: velocity` expressions — one target, one file per subject. Each input gets a typed
//! error that names the problem (file, line, element, key, constraint), or, where it is legal,
//! finite results in bounded work.
//!
//! - `bad_input`: errors name the file, element, key, frame and constraint;
//! - `urdf_robustness`: the loader on real-robot habits and hostile URDF values;
//! - `hostile_input`: hostile numbers at the scene and prediction boundary;
//! - `fuzz_hostile`: proptest over hostile URDF numbers and scene fields;
//! - `velocity_bad_input`: malformed and over-long `kind: velocity` declarations;
//! - `payload`: a bad `payload:` names its field.

mod bad_input;
mod fuzz_hostile;
mod hostile_input;
mod payload;
mod urdf_robustness;
mod velocity_bad_input;
