//! Tests of the geometric processor: priority order, BSP splitting.
