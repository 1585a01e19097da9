//! Helpers for the closed-loop integration tests (see `tests/`).
