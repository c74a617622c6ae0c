//! harmonid's data layer: the dataset folder of `docs/data-format.md` (reader, writer,
//! validation, [`Dataset::from_parts`] for data made in memory), the length units, and the
//! message helpers they share. No estimation here: `ident`, `report`, `plan`, `experiment` and
//! the Python bindings read and write data through this crate.

pub mod conventions;
pub mod dataset;
pub mod import;
pub mod result;
pub mod text;
pub mod units;

pub use dataset::{
    Dataset, DatasetError, Direction, GivenNoise, Manifest, Measurement, MeasurementSpec, PerStep,
    Point, SweepSpec, SweepStep, Truth, TruthForce, TruthMode, TruthNoise, DATASET_FORMAT,
    FREQ_REL_TOL, MAX_MANIFEST_BYTES,
};
pub use units::{metres_per, parse_length, LengthError, LENGTH_UNITS};
