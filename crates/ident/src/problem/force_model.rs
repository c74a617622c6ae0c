//! The force model in use for a dataset (`Auto` resolved), or why the one asked for cannot be.

use super::IdentError;
use crate::settings::ForceModel;
use harmonid_data::Dataset;

/// The force model in use: `Auto` resolves to drive levels when every measurement gives them;
/// a gain model without drive levels is an error naming the measurement.
pub(super) fn resolve_force_model(
    requested: ForceModel,
    ds: &Dataset,
    manifest_path: &str,
) -> Result<ForceModel, IdentError> {
    let all_levels = ds
        .measurements
        .iter()
        .all(|m| m.spec.drive_levels_and_phases().is_some());
    Ok(
        match requested.resolved_for(
            all_levels,
            ds.measurements.iter().any(|m| m.spec.sweep.is_some()),
        ) {
            f @ (ForceModel::GainPerMeasurement | ForceModel::GainPerMode) if !all_levels => {
                let missing = ds
                    .measurements
                    .iter()
                    .find(|m| m.spec.drive_levels_and_phases().is_none())
                    .map(|m| m.spec.name.clone())
                    .unwrap_or_default();
                return Err(IdentError::Unsupported(format!(
                "{manifest_path}: the force model \"{f}\" needs drive_levels_v and drive_phases_rad in every measurement; \"{missing}\" has none (use the free-force model)"
            )));
            }
            f => f,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_model_messages_use_words_not_debug_names() {
        // Issue 11: Rust debug names (`GainPerMode`, `NotConverged { .. }`) reached users.
        let manifest = "format = \"harmonid-dataset/1\"\n[[measurement]]\nname = \"m1\"\ndrives_hz = [1000.0]\n";
        let csv = "shot,freq_hz,re,im\n0,1000,1,2\n";
        let ds = Dataset::from_readers(std::path::Path::new("d"), manifest, None, |_| {
            Ok(csv.as_bytes())
        })
        .expect("a dataset without drive levels");
        let e = resolve_force_model(ForceModel::GainPerMode, &ds, "d/dataset.toml")
            .expect_err("gains need drive levels")
            .to_string();
        assert!(
            e.contains("the force model \"gain per mode\" needs") && !e.contains("GainPerMode"),
            "{e}"
        );
        assert_eq!(ForceModel::Free.to_string(), "free forces");
    }
}
