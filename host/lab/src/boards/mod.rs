//! The two boards: the serial link, the files the sensor board stores, and the requests of
//! the beacon and sensor boards.

pub mod beacon;
pub mod files;
pub mod link;
pub mod pty;
pub mod sensor;
