//! Tests of the sensor model.
