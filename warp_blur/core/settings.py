"""Render settings: one keyword-only dataclass, per-method defaults and quality presets (SPEC §6)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from .errors import SettingsError

METHODS = ("accumulation", "stochastic", "analytic", "velocity")
QUALITIES = ("draft", "preview", "final")
TIME_BITS_ALLOWED = (0, 32, 64, 128, 256, 512, 1024)

#: SPEC §6 defaults when no --quality is given.
DEFAULT_SAMPLES = {"accumulation": 64, "stochastic": 64, "analytic": 16, "velocity": 8}
DEFAULT_TIME_BITS = 128
#: motion segments without a preset (analytic's default, stochastic at every preset): 0.5 px /
#: 0.002 of the path since session 67 (0.25 / 0.001 before, analytic's final keeps it). Chords
#: straddle a curving path since session 64 (chords.py), so they stray from it about as far as
#: the tighter bound's did: analytic's default on deep_overlap 17-25% faster at RMSE 0.00078
#: against 0.00076, stochastic-64 15% faster at 0.002053 against 0.002046; demo's cube 4 segments
#: for 8 (RMSE 0.000473 against 0.000472); rotation and the straight-line bench scenes keep
#: theirs (bench_tradeoff, docs/benchmarks.md)
DEFAULT_SEGMENT_ERROR_PX = 0.5
DEFAULT_SEGMENT_TIME_ERROR = 0.002
#: the finer bound: analytic's final preset, and its exact spans (time_bits 0) without a preset,
#: whose error the motion would set otherwise (deep_overlap's exact RMSE 0.00019 at the default
#: bound against 0.00008 at this one)
FINE_SEGMENT_ERROR_PX = 0.25
FINE_SEGMENT_TIME_ERROR = 0.001

#: Quality presets: method -> preset -> {setting: value}. An explicit setting always wins.
QUALITY_PRESETS: dict[str, dict[str, dict[str, float]]] = {
    # chosen from the measured Pareto front (bench/bench_tradeoff.py, README "Quality presets")
    "accumulation": {"draft": {"samples": 16}, "preview": {"samples": 64}, "final": {"samples": 256}},
    "stochastic": {"draft": {"samples": 16}, "preview": {"samples": 64}, "final": {"samples": 256}},
    "analytic": {
        # the draft linearises motion more coarsely (fewer motion segments, so fewer prisms): its
        # coverage is what costs, not its resolve (bench_tradeoff, issue 18). 256 bits, not 128:
        # -1 to +6% time on the six bench scenes in alternated rounds, the error 1.0-4.1x lower
        # (session 63; 128 against 64 in session 55: 0-6% more time, 1.0-1.8x lower). Its segments
        # 1.5 px / 0.006 of the path, not 1 / 0.004, since chords straddle the path (session 64):
        # deep_overlap -10% at RMSE 0.00061 (was 0.00081 before the straddle), the other five
        # bench scenes' segments unchanged.
        "draft": {"time_bits": 256, "samples": 2, "segment_error_px": 1.5, "segment_time_error": 0.006},
        # preview: the draft's old segments (1 px / 0.004) with final's 512 bits and 4 shading
        # pieces (session 64, alternated against 256 bits at 0.5 px / 0.002): rotation -14% at
        # RMSE 0.00055 (was 0.00059; its 32 segments were final's), deep_overlap -4% at 0.00033
        # (0.00041), demo -9% at 0.00064 (0.00060), near_plane and crossing +2 / +6% at half the
        # error (final's images), large +3% at 0.00044 (0.00049)
        "preview": {"time_bits": 512, "samples": 4, "segment_error_px": 1.0, "segment_time_error": 0.004},
        "final": {"time_bits": 512, "samples": 16, "segment_error_px": FINE_SEGMENT_ERROR_PX,
                  "segment_time_error": FINE_SEGMENT_TIME_ERROR},
    },
    "velocity": {"draft": {"samples": 4}, "preview": {"samples": 8}, "final": {"samples": 16}},
}

#: Shadow presets by quality (every method): texels per map side and samples per area light.
SHADOW_PRESETS = {"draft": {"shadow_map_size": 256, "light_samples": 1},
                  "preview": {"shadow_map_size": 512, "light_samples": 4},
                  "final": {"shadow_map_size": 1024, "light_samples": 9}}
DEFAULT_SHADOW_MAP_SIZE = 512
DEFAULT_LIGHT_SAMPLES = 1
SHADOW_MODES = ("auto", "warped", "direct", "off")
#: How far (pixels) an implicit sphere's facets may fall inside its silhouette (its icosphere level
#: follows its size on screen, usd/tessellate.sphere_levels), by quality; the default is accurate
#: against a finer tessellation (bench/bench_particles.py).
SPHERE_ERROR_PRESETS = {"draft": 0.1, "preview": 0.05, "final": 0.0125}
DEFAULT_SPHERE_ERROR_PX = 0.025


@dataclass(frozen=True, kw_only=True)
class RenderSettings:
    """Everything that decides a frame's pixels besides the stage and frame.

    Attributes:
        method: one of METHODS.
        samples: instants (accumulation), samples per pixel (stochastic), shading-sample cap per
            interval (analytic) or gather samples (velocity); None = preset or SPEC default.
        time_bits: analytic bitmask bits per pixel (0 = exact spans); None = preset or 128.
        quality: optional preset name (draft, preview, final).
        seed: stochastic seed (stochastic only).
        spatial_samples: n -> n×n stratified sub-pixel positions (1 = pixel centre).
        shutter: (open, close) offsets in time codes overriding the camera's shutter.
        threads: worker threads for tiles (None = every core).
        aovs: AOV names to compute ("Z", "motion", "coverage").
        skip_invalid: drop prims with invalid geometry (with a warning) instead of failing.
        segment_error_px: max screen error of linearised motion segments, pixels (analytic and
            stochastic); None = preset or 0.5 (analytic's exact spans, time_bits 0: 0.25).
        segment_time_error: max linearisation error relative to a vertex's screen path (≈ the
            error in the time an edge covers a pixel, as a share of the shutter); None = preset
            or 0.002 (exact spans: 0.001).
        sphere_error_px: how far (pixels) an implicit sphere's facets may fall inside its silhouette:
            its icosphere level (20-1280 triangles) follows its size on screen; None = preset
            (draft 0.1, preview 0.05, final 0.0125) or 0.025.
        max_segments: upper bound of motion segments per prim (power of two).
        memory_budget_mb: analytic interval arrays above this render in pixel bands; accumulation
            records still pixels' hits only within it (else renders them at every instant), and
            keeps its instants' positions for the test of lights that shadow nothing lit only
            within 1/8 of it.
        frame_memory_limit_mb: a frame whose per-pixel buffers are estimated above this is refused
            before any work (memory.py); None = three quarters of physical memory.
        soft_edge_radius: velocity method: blur radius (pixels) of the soft-edge velocity buffer (0 = off).
        velocity_extrude: velocity method: vertex-trail extrusion (vertices facing the motion at
            shutter close, the others at open) before the gather.
        front_blur, back_blur: velocity method: blur strength factors where the surface faces
            along / against its screen motion.
        shadows: shadow maps "warped" from a few key maps, "direct" (a map rendered per instant:
            the reference), "off" (lights unoccluded), or "auto" (default: what measured fastest on
            the CPU, direct for stochastic, analytic and velocity, warped for accumulation, whose
            instants then share warped map instants).
        shadow_map_size: texels per shadow-map side (power of two); None = preset or 512.
        shadow_grid: warp control-point cells per map side (power of two; the map size = one per texel).
        shadow_times: map instants over the shutter (comparisons interpolated between them) for
            stochastic, analytic and warped accumulation with more instants than this; direct
            accumulation renders a map per instant; 1 when nothing moves in a light's view.
        shadow_keys: most key maps per light in warped mode (open and close, more where light-space
            motion is not linear).
        light_samples: point samples of an area light (soft shadows); None = preset or 1 (hard).
        shadow_bias, shadow_normal_bias: depth bias and receiver normal offset, in texels.
        shadow_pcf: percentage-closer filter radius in texels (0 = bilinear 2×2).
        shadow_memory_mb: budget for one frame's shadow maps (fewer instants above it).
        device: Warp device ("cpu" or "cuda").
    """

    method: str = "accumulation"
    samples: int | None = None
    time_bits: int | None = None
    quality: str | None = None
    seed: int | None = None
    spatial_samples: int = 1
    shutter: tuple[float, float] | None = None
    threads: int | None = None
    aovs: tuple[str, ...] = ("Z", "motion")
    skip_invalid: bool = False
    segment_error_px: float | None = None
    segment_time_error: float | None = None
    sphere_error_px: float | None = None
    max_segments: int = 128
    memory_budget_mb: float = 2048.0
    frame_memory_limit_mb: float | None = None
    soft_edge_radius: float = 2.0
    velocity_extrude: bool = False
    front_blur: float = 1.0
    back_blur: float = 1.0
    shadows: str = "auto"
    shadow_map_size: int | None = None
    shadow_grid: int = 128
    shadow_times: int = 8
    shadow_keys: int = 5
    light_samples: int | None = None
    shadow_bias: float = 1.0
    shadow_normal_bias: float = 1.5
    shadow_pcf: int = 0
    shadow_memory_mb: float = 1024.0
    device: str = "cpu"
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise SettingsError(f"unknown method '{self.method}' (choose from {', '.join(METHODS)})")
        if self.quality is not None and self.quality not in QUALITIES:
            raise SettingsError(f"unknown quality '{self.quality}' (choose from {', '.join(QUALITIES)})")
        if self.time_bits is not None and self.method != "analytic":
            raise SettingsError("--time-bits applies to the analytic method only")
        if self.seed is not None and self.method != "stochastic":
            raise SettingsError("--seed applies to the stochastic method only")
        if self.time_bits is not None and self.time_bits not in TIME_BITS_ALLOWED:
            raise SettingsError(f"time bits must be one of {TIME_BITS_ALLOWED} (0 = exact), got {self.time_bits}")
        if self.samples is not None and not (1 <= self.samples <= 1 << 16):
            raise SettingsError(f"samples must be between 1 and 65536, got {self.samples}")
        if self.spatial_samples < 1 or self.spatial_samples > 16:
            raise SettingsError(f"spatial samples must be between 1 and 16, got {self.spatial_samples}")
        if self.frame_memory_limit_mb is not None and not self.frame_memory_limit_mb > 0:
            raise SettingsError(f"memory limit must be a positive number of MiB, got {self.frame_memory_limit_mb}")
        for name in ("segment_error_px", "segment_time_error", "sphere_error_px"):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise SettingsError(f"{name} must be a positive number, got {value}")
        if self.threads is not None and self.threads < 1:
            raise SettingsError(f"threads must be at least 1, got {self.threads}")
        if self.max_segments < 1 or self.max_segments & (self.max_segments - 1):
            raise SettingsError("max_segments must be a power of two")
        if self.shadows not in SHADOW_MODES:
            raise SettingsError(f"unknown shadow mode '{self.shadows}' (choose from {', '.join(SHADOW_MODES)})")
        for name in ("shadow_map_size", "shadow_grid"):
            v = getattr(self, name)
            if v is not None and not (1 <= v <= 8192 and v & (v - 1) == 0):
                raise SettingsError(f"{name.replace('_', ' ')} must be a power of two up to 8192, got {v}")
        if not 1 <= self.shadow_times <= 256:
            raise SettingsError(f"shadow times must be between 1 and 256, got {self.shadow_times}")
        if not 2 <= self.shadow_keys <= 65:
            raise SettingsError(f"shadow keys must be between 2 and 65, got {self.shadow_keys}")
        if self.light_samples is not None and not 1 <= self.light_samples <= 256:
            raise SettingsError(f"light samples must be between 1 and 256, got {self.light_samples}")
        if not 0 <= self.shadow_pcf <= 8:
            raise SettingsError(f"shadow PCF radius must be between 0 and 8, got {self.shadow_pcf}")
        bad = [a for a in self.aovs if a not in ("Z", "motion", "coverage")]
        if bad:
            raise SettingsError(f"unknown AOV '{bad[0]}' (choose from Z, motion, coverage)")

    def _preset(self, name: str):
        if self.quality is None:
            return None
        return QUALITY_PRESETS[self.method][self.quality].get(name)

    @property
    def resolved_samples(self) -> int:
        """Samples after explicit value > quality preset > SPEC default."""
        if self.samples is not None:
            return self.samples
        preset = self._preset("samples")
        return preset if preset is not None else DEFAULT_SAMPLES[self.method]

    @property
    def resolved_time_bits(self) -> int:
        """Analytic time bits after explicit value > quality preset > 128."""
        if self.time_bits is not None:
            return self.time_bits
        preset = self._preset("time_bits")
        return preset if preset is not None else DEFAULT_TIME_BITS

    @property
    def _exact_spans(self) -> bool:
        """Analytic's exact spans (time_bits 0), which take the finer motion bound by default."""
        return self.method == "analytic" and self.resolved_time_bits == 0

    @property
    def resolved_segment_error_px(self) -> float:
        """Motion-segment screen error after explicit value > quality preset > 0.5 px (0.25 px
        for analytic's exact spans)."""
        if self.segment_error_px is not None:
            return self.segment_error_px
        preset = self._preset("segment_error_px")
        if preset is not None:
            return preset
        return FINE_SEGMENT_ERROR_PX if self._exact_spans else DEFAULT_SEGMENT_ERROR_PX

    @property
    def resolved_segment_time_error(self) -> float:
        """Motion-segment error relative to the screen path after explicit > preset > 0.002
        (0.001 for analytic's exact spans)."""
        if self.segment_time_error is not None:
            return self.segment_time_error
        preset = self._preset("segment_time_error")
        if preset is not None:
            return preset
        return FINE_SEGMENT_TIME_ERROR if self._exact_spans else DEFAULT_SEGMENT_TIME_ERROR

    @property
    def resolved_sphere_error_px(self) -> float:
        """Sphere facet error after explicit value > quality preset > 0.025 px."""
        if self.sphere_error_px is not None:
            return self.sphere_error_px
        return SPHERE_ERROR_PRESETS[self.quality] if self.quality else DEFAULT_SPHERE_ERROR_PX

    @property
    def resolved_shadow_map_size(self) -> int:
        if self.shadow_map_size is not None:
            return self.shadow_map_size
        return SHADOW_PRESETS[self.quality]["shadow_map_size"] if self.quality else DEFAULT_SHADOW_MAP_SIZE

    @property
    def resolved_light_samples(self) -> int:
        if self.light_samples is not None:
            return self.light_samples
        return SHADOW_PRESETS[self.quality]["light_samples"] if self.quality else DEFAULT_LIGHT_SAMPLES

    @property
    def resolved_shadows(self) -> str:
        return self.shadows

    @property
    def resolved_seed(self) -> int:
        return 0 if self.seed is None else self.seed

    def replace(self, **changes) -> "RenderSettings":
        return dataclasses.replace(self, **changes)

    def describe(self) -> dict:
        """Settings that decide pixels, as plain values (EXR header, --resume fingerprint)."""
        d = {"method": self.method, "samples": self.resolved_samples,
             "spatial_samples": self.spatial_samples, "shutter": self.shutter,
             "segment_error_px": self.segment_error_px, "segment_time_error": self.segment_time_error,
             "sphere_error_px": self.resolved_sphere_error_px, "max_segments": self.max_segments,
             "shadows": self.resolved_shadows}
        if self.resolved_shadows != "off":
            d.update(shadow_map_size=self.resolved_shadow_map_size, shadow_grid=self.shadow_grid,
                     shadow_times=self.shadow_times, shadow_keys=self.shadow_keys,
                     light_samples=self.resolved_light_samples, shadow_bias=self.shadow_bias,
                     shadow_normal_bias=self.shadow_normal_bias, shadow_pcf=self.shadow_pcf)
        if self.method in ("analytic", "stochastic"):
            # the bound the motion plan used (a default that changes between versions changes the
            # fingerprint: --resume renders such a frame again)
            d.update(segment_error_px=self.resolved_segment_error_px,
                     segment_time_error=self.resolved_segment_time_error)
        if self.method == "analytic":
            d["time_bits"] = self.resolved_time_bits
        if self.method == "stochastic":
            d["seed"] = self.resolved_seed
        if self.method == "velocity":
            d.update(soft_edge_radius=self.soft_edge_radius, extrude=self.velocity_extrude,
                     front_blur=self.front_blur, back_blur=self.back_blur)
        return d
