//! The integration tests of the `harmonid` package, one test binary (`cargo test --release --test it`):
//! each module was a test file of its own, and each of those was a statically linked release binary
//! of the whole tree to build and link. Run one module with `cargo test --release --test it -- NAME::`.

mod broken_inputs;
mod check_cli;
mod compare_models;
mod data_format_docs;
mod discover;
mod drive_ladder;
mod error_floor;
mod given_noise;
mod goodness_of_fit;
mod guess_support;
mod hardening_cli;
mod identify_calibration;
mod identify_cli;
mod identify_consistency;
mod identify_shared;
mod import_simulated;
mod long_record;
mod mix_cli;
mod model_broken;
mod model_docs;
mod noise_study;
mod nonlinear_damping;
mod parametric_pumping;
mod plan_cli;
mod plan_closed_loop;
mod plan_mc_support;
mod plan_robust_mc;
mod plan_roundtrip_mc;
mod pumping_cli;
mod readme_quickstart;
mod report_cli;
mod roundtrip;
mod roundtrip_noise;
mod sim_cli;
mod sim_dataset;
mod sim_dc;
mod sim_sweep_two_tone;
mod sim_td;
mod sim_td_noise;
mod stdout_pipe_cli;
mod stepped_scale;
mod stepped_sweep_branches;
mod sweep_plot;
mod ten_mode_string;
