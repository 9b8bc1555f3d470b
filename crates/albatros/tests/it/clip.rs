//! Tests: clip.
