//! The instruction-set level, chosen at run time: one binary, every x86-64 CPU at its
//! full speed.
//!
//! A binary built for the x86-64 baseline detects the CPU once and runs every kernel at
//! the best [`Level`] it has:
//!
//! | level | instructions | `f32x16` | `mul_add` |
//! |---|---|---|---|
//! | [`Level::Avx512`] (x86-64-v4 without CD) | AVX-512 F, BW, DQ, VL | one 512-bit register | fused |
//! | [`Level::Avx2`] (x86-64-v3) | AVX2 and FMA | two 256-bit registers | fused |
//! | [`Level::Baseline`] | what the build was compiled for (SSE2 on x86-64) | `wide` | fused iff [`FUSED_MUL_ADD`](crate::FUSED_MUL_ADD) |
//!
//! [`dispatch`] turns the level and a [`LaneKind`] into a lane type once, outside every
//! loop, and calls [`LaneFn::call`] with it. At the two x86 levels the call runs inside a
//! function compiled for the level's instructions (`#[target_feature]`), on lane types of
//! this crate written on `core::arch` intrinsics; `wide` cannot serve there, because it
//! fixes its instructions (and whether `mul_add` is fused) when it is compiled. The
//! generic code under [`LaneFn::call`] is inlined into that function and so compiled for
//! the level too: mark `call` and what it calls `#[inline(always)]`, and keep closures out
//! of its loops (the compiler may keep a closure out of line, where every intrinsic becomes
//! a call).
//!
//! **The same bits at every level with FMA.** Every operation of [`Lane`] is one IEEE 754
//! operation at every level, and `mul_add` is fused at both x86 levels, so AVX2 and AVX-512
//! give the same bits, lane width by lane width and against their scalar lane type. The
//! baseline level of a build without FMA (the default `x86_64` target) rounds `mul_add`
//! twice, as it always has: a CPU without FMA (x86 before 2013, some Atom-class cores, and
//! virtual machines that hide AVX) gets equally accurate but different bits.
//!
//! **Forcing a level.** The environment variable [`ENV_VAR`] (`LEVELSET_SIMD`) set to
//! `baseline`, `avx2` or `avx512` forces that level for experiments and tests. A value the
//! CPU cannot run, or not one of these, is not honoured: [`Level::active`] then falls back
//! to the detected level and [`check_env`] says why (the command-line tools refuse to start).

use crate::lane::{Lane, LaneKind};
use std::sync::OnceLock;

/// The environment variable that forces a [`Level`]: `baseline`, `avx2` or `avx512` (any
/// case; empty is unset).
pub const ENV_VAR: &str = "LEVELSET_SIMD";

/// An instruction-set level the kernels can run at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Level {
    /// What the build was compiled for, through `wide` (SSE2 on the x86-64 baseline; NEON
    /// on aarch64).
    Baseline,
    /// x86-64-v3: AVX2 and FMA.
    Avx2,
    /// AVX-512 F, BW, DQ and VL (and AVX2, FMA): x86-64-v4 without AVX-512 CD, which the
    /// kernels do not use.
    Avx512,
}

impl Level {
    /// Every level, lowest first.
    pub const ALL: [Level; 3] = [Level::Baseline, Level::Avx2, Level::Avx512];

    /// `"baseline"`, `"avx2"`, `"avx512"`: the values of [`ENV_VAR`].
    pub const fn name(self) -> &'static str {
        match self {
            Level::Baseline => "baseline",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }

    /// The inverse of [`Level::name`].
    pub fn from_name(name: &str) -> Option<Level> {
        Level::ALL.into_iter().find(|l| l.name() == name)
    }

    /// A line for reports: the level and its instructions, e.g.
    /// `"avx512 (AVX-512 F/BW/DQ/VL, FMA)"`.
    pub fn describe(self) -> String {
        let what = match self {
            Level::Baseline if FUSED_BASELINE => "the build's own target features, FMA",
            Level::Baseline => "the build's own target features, no FMA",
            Level::Avx2 => "x86-64-v3: AVX2, FMA",
            Level::Avx512 => "AVX-512 F/BW/DQ/VL, FMA",
        };
        format!("{} ({what})", self.name())
    }

    /// Whether [`Lane::mul_add`] is fused (one rounding) at this level.
    pub const fn fused(self) -> bool {
        match self {
            Level::Baseline => FUSED_BASELINE,
            Level::Avx2 | Level::Avx512 => true,
        }
    }

    /// Whether this CPU can run the level (detected once).
    pub fn available(self) -> bool {
        match self {
            Level::Baseline => true,
            Level::Avx2 | Level::Avx512 => detected() >= self,
        }
    }

    /// The highest level this CPU can run.
    pub fn detected() -> Level {
        detected()
    }

    /// The level [`dispatch`] runs at: the one [`ENV_VAR`] forces if the CPU can run it,
    /// else [`Level::detected`]. Decided once per process.
    pub fn active() -> Level {
        resolved().0
    }

    /// The lane kind the library uses unless told otherwise at this level: `f32x16` at
    /// AVX-512 (one register) and in baseline builds with AVX-512F, `f32x8` otherwise (one
    /// AVX register, two SSE registers at an SSE2 baseline), or `f32` without the `simd`
    /// feature.
    pub const fn default_lanes(self) -> LaneKind {
        if !cfg!(feature = "simd") {
            LaneKind::F32
        } else {
            match self {
                Level::Avx512 => LaneKind::F32x16,
                Level::Baseline if cfg!(target_feature = "avx512f") => LaneKind::F32x16,
                _ => LaneKind::F32x8,
            }
        }
    }
}

// The default lane kind follows the `simd` feature at every level: SIMD lanes with it, `f32`
// without. Evaluated wherever the crate compiles (`cargo check` and clippy too), so every
// build of either feature set checks it.
const _: () = {
    let mut i = 0;
    while i < Level::ALL.len() {
        let lanes = Level::ALL[i].default_lanes().lanes();
        let follows = if cfg!(feature = "simd") { lanes >= 8 } else { lanes == 1 };
        assert!(follows, "the default lanes do not follow the `simd` feature");
        i += 1;
    }
};

impl std::fmt::Display for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Whether the baseline level fuses `mul_add` (the build enables FMA, or targets aarch64).
const FUSED_BASELINE: bool = crate::lane::FUSED_MUL_ADD;

/// Why [`ENV_VAR`] was not honoured, if it was set and was not: a message for the user.
///
/// # Errors
/// The variable names no level, or one this CPU cannot run.
pub fn check_env() -> Result<(), String> {
    match &resolved().1 {
        None => Ok(()),
        Some(e) => Err(e.clone()),
    }
}

fn resolved() -> &'static (Level, Option<String>) {
    static ACTIVE: OnceLock<(Level, Option<String>)> = OnceLock::new();
    ACTIVE.get_or_init(|| {
        let best = detected();
        let Some(v) = std::env::var_os(ENV_VAR) else { return (best, None) };
        let v = v.to_string_lossy().trim().to_ascii_lowercase();
        if v.is_empty() {
            // Set but empty: as if unset (`LEVELSET_SIMD= command`).
            return (best, None);
        }
        match Level::from_name(&v) {
            Some(l) if l.available() => (l, None),
            Some(l) => (
                best,
                Some(format!(
                    "{ENV_VAR}={v}: this CPU cannot run {l} (the highest level it has is {best})"
                )),
            ),
            None => (best, Some(format!("{ENV_VAR}={v}: not a level (baseline, avx2 or avx512)"))),
        }
    })
}

#[cfg(target_arch = "x86_64")]
fn detected() -> Level {
    static DETECTED: OnceLock<Level> = OnceLock::new();
    *DETECTED.get_or_init(|| {
        use std::arch::is_x86_feature_detected as has;
        let avx2 = has!("avx2") && has!("fma");
        if avx2 && has!("avx512f") && has!("avx512bw") && has!("avx512dq") && has!("avx512vl") {
            Level::Avx512
        } else if avx2 {
            Level::Avx2
        } else {
            Level::Baseline
        }
    })
}

#[cfg(not(target_arch = "x86_64"))]
fn detected() -> Level {
    Level::Baseline
}

/// Code generic over the lane type, handed to [`dispatch`]: the generic closure Rust does
/// not have. Implement `call` with `#[inline(always)]` so that it, and the kernels it runs,
/// are compiled for the level [`dispatch`] chose.
pub trait LaneFn {
    /// What the call returns.
    type Output;
    /// Runs the code with lane type `L`.
    fn call<L: Lane>(self) -> Self::Output;
}

/// Calls `f` with the lane type of `kind` at [`Level::active`], inside a function compiled
/// for that level's instructions. The choice is made here, once per call.
#[inline]
pub fn dispatch<F: LaneFn>(kind: LaneKind, f: F) -> F::Output {
    match Level::active() {
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => {
            // SAFETY: `Level::active` returns a level only if the CPU has its features.
            unsafe { x86::avx512::all(kind, f) }
        }
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => {
            // SAFETY: as above.
            unsafe { x86::avx2::all(kind, f) }
        }
        _ => baseline(kind, f),
    }
}

/// [`dispatch`] with two lane kinds only: the level's default ([`Level::default_lanes`])
/// if `simd`, else one voxel (`LaneKind::F32`). What an engine that offers just these two
/// uses: each call site is compiled twice per level instead of four times.
#[inline]
pub fn dispatch_default<F: LaneFn>(simd: bool, f: F) -> F::Output {
    match Level::active() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::active` returns a level only if the CPU has its features.
        Level::Avx512 => unsafe { x86::avx512::default(simd, f) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Level::Avx2 => unsafe { x86::avx2::default(simd, f) },
        _ => {
            if simd {
                f.call::<crate::DefaultLane>()
            } else {
                f.call::<f32>()
            }
        }
    }
}

/// [`dispatch`] with the one-voxel lane type (`LaneKind::F32`) only: for code that
/// gathers each voxel's values into a point window ([`crate::BoxWindow`] and its kin),
/// which serves no wider lane type.
#[inline]
pub fn dispatch_one<F: LaneFn>(f: F) -> F::Output {
    match Level::active() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::active` returns a level only if the CPU has its features.
        Level::Avx512 => unsafe { x86::avx512::one(f) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Level::Avx2 => unsafe { x86::avx2::one(f) },
        _ => f.call::<f32>(),
    }
}

/// [`dispatch`] at a given level, or `None` if this CPU cannot run it: for tests and
/// benchmarks that compare levels within one process.
pub fn dispatch_at<F: LaneFn>(level: Level, kind: LaneKind, f: F) -> Option<F::Output> {
    if !level.available() {
        return None;
    }
    Some(match level {
        Level::Baseline => baseline(kind, f),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has the level's features (checked above).
        Level::Avx512 => unsafe { x86::avx512::all(kind, f) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Level::Avx2 => unsafe { x86::avx2::all(kind, f) },
        #[cfg(not(target_arch = "x86_64"))]
        _ => unreachable!("only the baseline level is available off x86-64"),
    })
}

fn baseline<F: LaneFn>(kind: LaneKind, f: F) -> F::Output {
    crate::with_lane!(kind, |L| f.call::<L>())
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::LaneFn;
    use crate::lane::LaneKind;
    use crate::x86::{Pair, S1, X16, X4, X8};

    /// The three entry points of one level, compiled for its `$features`: every lane kind
    /// (`$x16` the level's `f32x16`), one voxel, and the engine's two (`$default` the
    /// level's default SIMD kind).
    macro_rules! level {
        ($level:ident, $features:literal, $cpu:literal, x16 $x16:ty, default $default:ty) => {
            pub(super) mod $level {
                use super::*;

                /// Every lane kind.
                ///
                /// # Safety
                #[doc = concat!("The CPU must have ", $cpu, ".")]
                #[target_feature(enable = $features)]
                pub(in super::super) unsafe fn all<F: LaneFn>(kind: LaneKind, f: F) -> F::Output {
                    match kind {
                        LaneKind::F32 => f.call::<S1>(),
                        LaneKind::F32x4 => f.call::<X4>(),
                        LaneKind::F32x8 => f.call::<X8>(),
                        LaneKind::F32x16 => f.call::<$x16>(),
                    }
                }

                /// One voxel.
                ///
                /// # Safety
                #[doc = concat!("The CPU must have ", $cpu, ".")]
                #[target_feature(enable = $features)]
                pub(in super::super) unsafe fn one<F: LaneFn>(f: F) -> F::Output {
                    f.call::<S1>()
                }

                /// The level's default lanes if `simd` (one voxel without the `simd`
                /// feature), else one voxel.
                ///
                /// # Safety
                #[doc = concat!("The CPU must have ", $cpu, ".")]
                #[target_feature(enable = $features)]
                pub(in super::super) unsafe fn default<F: LaneFn>(simd: bool, f: F) -> F::Output {
                    if simd && cfg!(feature = "simd") {
                        f.call::<$default>()
                    } else {
                        f.call::<S1>()
                    }
                }
            }
        };
    }

    level!(avx2, "avx2,fma", "AVX2 and FMA", x16 Pair<X8>, default X8);
    level!(
        avx512,
        "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma",
        "AVX-512 F, BW, DQ, VL, AVX2 and FMA",
        x16 X16,
        default X16
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dispatch runs the active level's default lanes (which follow the `simd` feature:
    /// checked at compile time, above), or scalar lanes when asked.
    #[test]
    fn dispatch_runs_the_default_lanes() {
        struct Width;
        impl LaneFn for Width {
            type Output = usize;
            fn call<L: Lane>(self) -> usize {
                L::LANES
            }
        }
        let active = Level::active();
        assert_eq!(dispatch_default(true, Width), active.default_lanes().lanes());
        assert_eq!(dispatch_default(false, Width), 1);
        assert_eq!(dispatch_one(Width), 1);
    }
}
