//! The two boards: the serial link, and the beacon and sensor board commands.

pub mod beacon;
pub mod link;
pub mod sensor;
