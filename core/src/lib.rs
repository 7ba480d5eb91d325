//! # cta-core
//!
//! The body of math behind CTA, after Stancliffe (2010), *Analysis and design of a test
//! apparatus for resolving near-field effects associated with using a coarse sun sensor as
//! part of a 6-DOF solution* (Texas A&M). Equation numbers in doc comments are the thesis's.
//!
//! `no_std`; the `alloc` feature adds dynamically sized least-squares problems and `std`
//! (default) is for the host. Everything numeric is generic over [`Real`] (`f32` on the
//! chip, `f64` on the host).
//!
//! Conventions (REFERENCE.md section 1): lengths in inches, angles in degrees at every
//! interface (radians inside), N = sensor-board frame, O = sensor-head frame,
//! `C = C(p)` maps N components to O components.
#![cfg_attr(not(feature = "std"), no_std)]
// Checks are written `!(x > 0.0)` on purpose: a NaN fails them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod real;
pub use real::Real;

pub mod collinearity;
pub mod crystal;
pub mod emulator;
pub mod glsdc;
pub mod magnitude_law;
pub mod mrp;
pub mod nearfield2d;
pub mod pattern;
pub mod trig;
pub mod uncertainty;

// On-chip 6-dof pose solution. Plain comments here: an outer doc comment would make rustdoc
// resolve the module's own intra-doc links from the crate root.
pub mod pose;
// Beacon modulation schedule.
pub mod schedule;
// Wire protocol shared by the boards and the host.
pub mod wire;
