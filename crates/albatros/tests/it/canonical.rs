//! Tests: canonical.
