//! Checks of a manifest against `DATA_FORMAT.md` that TOML parsing alone does not make.

use super::csv_read::{num_text as num, shown, MAX_FREQ_HZ};
use super::*;

/// Largest magnitude of a mode-shape value.
pub const MAX_SHAPE: f64 = 1e6;
/// Largest magnitude of a drive level (V or the manifest's unit).
pub const MAX_DRIVE_LEVEL: f64 = 1e12;

pub(super) fn validate_manifest(m: &Manifest, path: &Path) -> Result<(), DatasetError> {
    let err = |message: String| DatasetError::Manifest {
        path: path.to_path_buf(),
        message,
    };
    if m.format != DATASET_FORMAT {
        return Err(DatasetError::Format {
            path: path.to_path_buf(),
            found: m.format.clone(),
        });
    }
    if m.unit_scale().is_none() {
        return Err(err(format!(
            "displacement_unit = \"{}\" is not a length unit ({}) nor \"V\" (volts, no sensor calibration)",
            m.displacement_unit,
            crate::units::length_unit_names()
        )));
    }
    let mut seen = std::collections::HashSet::new();
    for p in &m.points {
        if !seen.insert(p.name.as_str()) {
            return Err(err(format!("point \"{}\" is declared twice", p.name)));
        }
        for (mode, v) in &p.shape {
            if !(v.is_finite() && v.abs() <= MAX_SHAPE) {
                return Err(err(format!(
                    "point \"{}\": shape of {mode} is {v}, expected a finite number of magnitude at most {MAX_SHAPE:e}",
                    shown(&p.name)
                )));
            }
        }
    }
    for (mode, f) in &m.nominal_hz {
        if !(f.is_finite() && *f > 0.0 && *f <= MAX_FREQ_HZ) {
            return Err(err(format!(
                "nominal_hz.{} = {}, expected a positive frequency in Hz (at most {MAX_FREQ_HZ:e})",
                shown(mode),
                num(*f)
            )));
        }
    }
    if m.measurements.is_empty() && m.sweeps.is_empty() {
        return Err(err(
            "no [[measurement]] or [[sweep]] is listed; add one per drive configuration, with its name and drives_hz (docs/data-format.md)"
                .into(),
        ));
    }
    let mut names = std::collections::HashSet::new();
    for ms in &m.measurements {
        if ms.name.trim().is_empty() {
            return Err(err(
                "a [[measurement]] has an empty name; give each a unique name".into(),
            ));
        }
        if !names.insert(ms.name.as_str()) {
            return Err(err(format!(
                "measurement \"{}\" is declared twice; names must be unique",
                ms.name
            )));
        }
        check_spec(ms).map_err(err)?;
    }
    for sw in &m.sweeps {
        if sw.name.trim().is_empty() {
            return Err(err(
                "a [[sweep]] has an empty name; give each a unique name".into(),
            ));
        }
        if !names.insert(sw.name.as_str()) {
            return Err(err(format!(
                "sweep \"{}\" has the name of another sweep or measurement; names must be unique",
                sw.name
            )));
        }
        super::sweep::check_sweep(sw).map_err(err)?;
        for k in 0..sw.drives_hz.len() {
            check_spec(&sw.step_spec(k)).map_err(err)?;
        }
    }
    Ok(())
}

/// The checks of one measurement's entry (file inside the folder, drive tones, levels and
/// phases), as a message naming it.
pub(super) fn check_spec(ms: &MeasurementSpec) -> Result<(), String> {
    let err = |m: String| m;
    let file = ms.file_name();
    let fp = Path::new(&file);
    if fp.is_absolute()
        || fp
            .components()
            .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
        || !matches!(fp.components().next_back(), Some(Component::Normal(_)))
    {
        return Err(err(format!(
                "measurement \"{}\": file \"{}\" must name a CSV file inside the dataset folder, e.g. file = \"{}.csv\"",
                shown(&ms.name),
                shown(&file),
                shown(&ms.name)
            )));
    }
    if ms.drives_hz.is_empty() {
        return Err(err(format!(
            "measurement \"{}\": drives_hz is empty; list every drive tone in Hz",
            ms.name
        )));
    }
    for d in &ms.drives_hz {
        if !(d.is_finite() && *d > 0.0 && *d <= MAX_FREQ_HZ) {
            return Err(err(format!(
                    "measurement \"{}\": drive frequency {} is not a positive number of Hz (at most {MAX_FREQ_HZ:e})",
                    ms.name,
                    num(*d)
                )));
        }
    }
    for (i, a) in ms.drives_hz.iter().enumerate() {
        for (j, b) in ms.drives_hz.iter().enumerate().skip(i + 1) {
            if (a - b).abs() <= FREQ_REL_TOL * a.max(*b) {
                return Err(err(format!(
                        "measurement \"{}\": drive tones {} and {} are the same frequency ({a} Hz and {b} Hz); list each tone once (two tones closer than 1e-9 relative cannot be told apart)",
                        ms.name,
                        i + 1,
                        j + 1
                    )));
            }
        }
    }
    for (key, v) in [
        ("drive_levels_v", &ms.drive_levels_v),
        ("drive_phases_rad", &ms.drive_phases_rad),
    ] {
        if let Some(v) = v {
            if v.len() != ms.drives_hz.len() {
                return Err(err(format!(
                        "measurement \"{}\": {key} has {} entries but drives_hz has {}; give one per drive tone, in drives_hz order",
                        ms.name,
                        v.len(),
                        ms.drives_hz.len()
                    )));
            }
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(err(format!(
                    "measurement \"{}\": {key} contains {x}, expected finite numbers",
                    ms.name
                )));
            }
            if key == "drive_levels_v" {
                if let Some((i, x)) = v
                    .iter()
                    .enumerate()
                    .find(|(_, x)| **x == 0.0 || x.abs() > MAX_DRIVE_LEVEL)
                {
                    return Err(err(format!(
                            "measurement \"{}\": drive_levels_v[{i}] = {}; a drive level must be non-zero and at most {MAX_DRIVE_LEVEL:e} in magnitude (remove a tone that was not driven from drives_hz)",
                            ms.name,
                            num(*x)
                        )));
                }
            }
        }
    }
    if ms.drive_levels_v.is_some() != ms.drive_phases_rad.is_some() {
        return Err(err(format!(
            "measurement \"{}\": give both drive_levels_v and drive_phases_rad, or neither",
            ms.name
        )));
    }
    check_pumps(ms).map_err(err)
}

/// A pump is its tones with a level and a phase each (the `pump` factor of the model's terms
/// is that signal): positive finite frequencies, finite levels and phases, one of each per tone.
fn check_pumps(ms: &MeasurementSpec) -> Result<(), String> {
    let name = &ms.name;
    if ms.pumps_hz.is_empty() {
        if ms.pump_levels.is_some() || ms.pump_phases_rad.is_some() {
            return Err(format!(
                "measurement \"{name}\": pump_levels or pump_phases_rad without pumps_hz; list the pump tones in Hz, or remove them"
            ));
        }
        return Ok(());
    }
    if let Some(f) = ms
        .pumps_hz
        .iter()
        .find(|f| !(f.is_finite() && **f > 0.0 && **f <= MAX_FREQ_HZ))
    {
        return Err(format!(
            "measurement \"{name}\": pump frequency {} is not a positive number of Hz (at most {MAX_FREQ_HZ:e})",
            num(*f)
        ));
    }
    for (key, v) in [
        ("pump_levels", &ms.pump_levels),
        ("pump_phases_rad", &ms.pump_phases_rad),
    ] {
        let Some(v) = v else {
            return Err(format!(
                "measurement \"{name}\": pumps_hz without {key}; the pump terms need the pump's level and phase of each tone (give pump_levels and pump_phases_rad, one per tone)"
            ));
        };
        if v.len() != ms.pumps_hz.len() {
            return Err(format!(
                "measurement \"{name}\": {key} has {} entries but pumps_hz has {}; give one per pump tone, in pumps_hz order",
                v.len(),
                ms.pumps_hz.len()
            ));
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!(
                "measurement \"{name}\": {key} contains {x}, expected finite numbers"
            ));
        }
    }
    Ok(())
}
