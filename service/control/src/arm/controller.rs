//! Algorithm 3 as a controller (to be written).
