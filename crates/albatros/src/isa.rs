//! Which copy of the VP's hot units runs on an x86-64 processor that has AVX-512.
//!
//! The subpixel processors, the colour computers, the VB's F1 and its readout each
//! have an AVX2 copy, tuned from session 7 to 25 on a Zen 3 (no AVX-512), and an
//! AVX-512 copy of session 6, written on a Zen 4 and not tuned since. On a Zen 4
//! again (session 26) the AVX2 copies are the faster: one thread at 1920 x 1080,
//! terrain 1.25-1.29x and default 1.25-1.44x, the raster alone 1.5x; the readout
//! alone default ~1.25x, terrain ~1.33x, city 0.95x (BENCHMARKS.md, session 26). So
//! the AVX2 copies run wherever the processor has AVX2, and the AVX-512 copies of
//! those units only when the environment asks for them with `ALBATROS_AVX512=1`
//! ([`avx512_asked`], read once a process), to measure them against the AVX2 ones.
//! The exact rule's vertex pixels on the SPPs' plain route (which the AVX2 route
//! does not take) keep their own AVX-512 detection.
//!
//! **Either way the image is the same, byte for byte**: every copy is tested bit for
//! bit against its unit's definition.

/// The environment variable that asks for the AVX-512 copies ([`avx512_asked`]).
pub const AVX512_VARIABLE: &str = "ALBATROS_AVX512";

/// Whether the environment asks for the AVX-512 copies of the SPPs, the colour
/// computers and F1 (`ALBATROS_AVX512=1`; the processor must still have AVX-512,
/// which each unit detects). Read once a process, so that a frame never mixes copies.
pub(crate) fn avx512_asked() -> bool {
    static ASKED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ASKED.get_or_init(|| std::env::var_os(AVX512_VARIABLE).is_some_and(|v| v == "1"))
}

/// Which copies of those units run in this process, for a report (`albatros bench`):
/// `"avx512"` when asked for ([`avx512_asked`]) on a processor with AVX-512F (each
/// unit then runs its AVX-512 copy where the processor has the further features it
/// needs), else `"avx2"` where the processor has AVX2, else `"portable"`.
pub fn copies() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if avx512_asked() && std::is_x86_feature_detected!("avx512f") {
            return "avx512";
        }
        if std::is_x86_feature_detected!("avx2") {
            return "avx2";
        }
    }
    "portable"
}
