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
//! ([`avx512_copies`], read once a process), to measure them against the AVX2 ones.
//! The exact rule's vertex pixels on the SPPs' plain route (which the AVX2 route
//! does not take) keep their own AVX-512 detection.
//!
//! **Either way the image is the same, byte for byte**: every copy is tested bit for
//! bit against its unit's definition.

/// The environment variable that asks for the AVX-512 copies ([`avx512_copies`]).
pub const AVX512_VARIABLE: &str = "ALBATROS_AVX512";

/// Whether the AVX-512 copies of the SPPs, the colour computers, F1 and the readout
/// run: the environment asks for them (`ALBATROS_AVX512=1`) and the processor has
/// AVX-512F (a unit whose copy needs further features detects those too). Found
/// once a process, so that a frame never mixes copies. Every unit chooses by this
/// one test, and so does F1's place (inside the AVX2 colour computers, or apart).
pub(crate) fn avx512_copies() -> bool {
    static CHOSEN: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *CHOSEN.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        let has = std::is_x86_feature_detected!("avx512f");
        #[cfg(not(target_arch = "x86_64"))]
        let has = false;
        has && std::env::var_os(AVX512_VARIABLE).is_some_and(|v| v == "1")
    })
}

/// Which copies of those units run in this process, for a report (`albatros bench`):
/// `"avx512"` ([`avx512_copies`]), else `"avx2"` where the processor has AVX2, else
/// `"portable"`.
pub fn copies() -> &'static str {
    if avx512_copies() {
        return "avx512";
    }
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") {
            return "avx2";
        }
    }
    "portable"
}
