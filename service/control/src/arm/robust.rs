//! The robust gain (7.39)–(7.41) (to be written).
