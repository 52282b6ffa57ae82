//! Parity with the official PyTorch reference: the golden fixtures in `../shared/fixtures`
//! (seeded random weights under their official names, inputs and expected outputs).

mod adapter;
mod backbone;
mod checkpoint;
mod fixture;
mod heads;
mod layers;
#[path = "../../../../tests/support/paths.rs"]
mod paths;
