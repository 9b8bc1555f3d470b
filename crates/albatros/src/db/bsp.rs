//! BSP tree over the static database (SYSTEM.md 2, Priority).
