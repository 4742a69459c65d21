//! Log-odds as OctoMap computes them, its update constants bit for bit, and
//! the map-level clamp (docs/math.md §4.2, §4.6).

/// How log-odds are bounded after an update (docs/math.md §4.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clamp {
    /// Lower bound (OctoMap: −2.0, p = 0.1192).
    pub min: f32,
    /// Upper bound (OctoMap: +3.5, p = 0.971).
    pub max: f32,
}

/// `ln(p / (1 − p))` in `f32`, as OctoMap computes its parameters.
pub fn logodds(p: f64) -> f32 {
    (p / (1.0 - p)).ln() as f32
}

/// OctoMap's hit update, `logodds(0.7)` = 0.8473 (docs/math.md §4.2), bit-exact.
pub const LOG_ODDS_HIT: f32 = f32::from_bits(0x3f58_e883);
/// OctoMap's miss update, `logodds(0.4)` = −0.4055, bit-exact.
pub const LOG_ODDS_MISS: f32 = f32::from_bits(0xbecf_991f);

impl Default for Clamp {
    /// OctoMap's clamp.
    fn default() -> Self {
        Clamp::OCTOMAP
    }
}

impl Clamp {
    /// OctoMap's defaults, `[logodds(0.1192), logodds(0.971)]` = [−2.00003, 3.51103]:
    /// the values its `.bt` reader gives free and occupied leaves.
    pub const OCTOMAP: Clamp = Clamp {
        min: f32::from_bits(0xc000_0075),
        max: f32::from_bits(0x4060_b4ba),
    };
    /// No map-level clamp (the paper's mode; per-value clamping happens in the OPDF).
    pub const NONE: Clamp = Clamp {
        min: f32::NEG_INFINITY,
        max: f32::INFINITY,
    };

    /// `v` clamped to `[min, max]`.
    #[inline]
    pub fn apply(&self, v: f32) -> f32 {
        v.clamp(self.min, self.max)
    }
}
