//! Sensor-board messages (firmware-sensor issue).
