//! End-to-end tests of the `robocal` binary, one test binary (one link of the whole
//! dependency tree): every command on real files ([`commands`]) and bad input across every
//! command and input file ([`hardening`]), data that read well and are wrong
//! ([`robustness`]), compensation toward a robot program ([`compensation`]), the pictures of a calibration ([`report`]), with one runner and CSV helpers ([`common`]).

mod commands;
mod common;
mod compensation;
mod datasets;
mod export;
mod hardening;
mod import;
mod planning;
mod probe;
mod reflectors;
mod report;
mod robustness;
