//! The frame list.
