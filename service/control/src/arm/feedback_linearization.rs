//! The feedback linearization (7.31) (to be written).
