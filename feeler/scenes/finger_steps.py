"""Scene kind ``finger-steps``: the finger skin slid over single steps (paper §4, Figs 3–6).

One strain history per (step height, speed); the skin level (L0, L1, L2) and the mesh
are chosen by the scene. Nothing is random: the scene has no seed.
"""
from __future__ import annotations

from dataclasses import dataclass

from feeler.errors import SceneError
from feeler.scene import param

__all__ = ["Scene", "Head", "Skin", "Loading", "Steps", "Model", "Mesh", "Neuron", "MAX_STEP_OF_PRESS"]

#: the tallest step as a share of the press depth. The skin models are linear about the
#: pressed state (L1 freezes the press's contact set; L0 and L1 are linear in the step;
#: L2 is small-strain linear elasticity). Measured on the coarse test mesh at 20 mm/s
#: (1 mm press): L1's peak step strain is 0.3 % off L2 at 15 µm, 6 % at 100 µm (a tenth
#: of the press, peak strain rate 18 %), 27 % at 500 µm (rate 95 %); at 1000 µm L2's
#: contact patch leaves its strip. The step's own strain is then 7 % at a tenth, 29 % at
#: a half: beyond a tenth the figures describe the models' linearisation, not a finger.
MAX_STEP_OF_PRESS = 0.1


@dataclass(frozen=True, kw_only=True)
class Head:
    kind: str = param(choices=("finger-steps",), doc="scene kind")
    name: str = param("finger-steps", doc="short name of the dataset")
    description: str = param("", doc="free text")


@dataclass(frozen=True, kw_only=True)
class Skin:
    e_mpa: tuple[float, ...] = param((0.14, 0.034, 0.080), lo=0.0, lo_open=True, hi=1000.0, min_len=3,
                                     doc="MPa, instantaneous Young's moduli: epidermis, dermis, hypodermis")
    nu: float = param(0.45, lo=0.0, hi=0.499, doc="Poisson's ratio of all layers")
    prony_ratio: float = param(0.5, lo=0.0, hi=0.99, doc="first-order Prony ratio g1 (relaxing fraction)")
    prony_tau_s: float = param(0.0129, lo=0.0, lo_open=True, hi=1000.0, doc="s, Prony time constant")
    radius_mm: float = param(8.0, lo=1.0, hi=50.0, doc="mm, radius of the half-cylinder finger")
    thickness_mm: tuple[float, ...] = param((0.45, 1.55), lo=0.0, lo_open=True, hi=20.0, min_len=2,
                                            doc="mm, epidermis and dermis thickness")
    corpuscle_width_mm: float = param(0.040, lo=0.0, lo_open=True, hi=1.0, doc="mm, corpuscle element along x")
    corpuscle_height_mm: float = param(0.050, lo=0.0, lo_open=True, hi=1.0, doc="mm, corpuscle element along y")
    corpuscle_depth_mm: float = param(0.5, lo=0.0, lo_open=True, hi=5.0, doc="mm, depth of the element's centre")


@dataclass(frozen=True, kw_only=True)
class Loading:
    press_mm: float = param(1.0, lo=0.0, lo_open=True, hi=5.0, doc="mm, press depth")
    press_s: float = param(0.1, lo=0.0, lo_open=True, hi=60.0, doc="s, duration of the press ramp")
    hold_s: float = param(1.0, lo=0.0, hi=60.0, doc="s, hold before the slide")
    slide_mm: float = param(10.0, lo=0.0, lo_open=True, hi=100.0, doc="mm, slide distance")
    speeds_mm_s: tuple[float, ...] = param((20.0, 40.0), lo=0.0, lo_open=True, hi=1000.0, min_len=1,
                                           doc="mm/s, sliding speeds")
    travel_step_mm: float = param(0.01, lo=0.0, lo_open=True, hi=1.0, doc="mm of travel per time step")


@dataclass(frozen=True, kw_only=True)
class Steps:
    heights_um: tuple[float, ...] = param((5.0, 7.5, 10.0, 12.5, 15.0), lo=0.0, lo_open=True, hi=1000.0,
                                          min_len=1, doc="µm, step heights (one run each)")
    position_mm: float = param(5.0, lo=-100.0, hi=100.0, doc="mm, step centre on the plate")
    edge_um: float = param(50.0, lo=0.0, hi=1000.0, doc="µm, ramp width rounding the step's edge")


@dataclass(frozen=True, kw_only=True)
class Mesh:
    h_contact_mm: float = param(0.025, lo=0.0, lo_open=True, hi=1.0, doc="mm, size along the contact strip")
    h_corpuscle_mm: float = param(0.01, lo=0.0, lo_open=True, hi=1.0, doc="mm, size at the corpuscle")
    h_far_mm: float = param(0.8, lo=0.0, lo_open=True, hi=10.0, doc="mm, largest size")
    grade: float = param(0.25, lo=0.0, lo_open=True, hi=5.0, doc="size growth per mm of distance")
    contact_half_width_mm: float = param(4.5, lo=0.0, lo_open=True, hi=50.0, doc="mm, candidate contact strip")


@dataclass(frozen=True, kw_only=True)
class Model:
    level: str = param("l1", choices=("l0", "l1", "l2"), doc="skin fidelity")
    l0_gain: float = param(1.0, lo=-1000.0, hi=1000.0, doc="L0 layering gain")
    l0_base: float = param(0.0, lo=-1.0, hi=1.0, doc="L0 pressed-state strain")


@dataclass(frozen=True, kw_only=True)
class Neuron:
    a: float = param(1.0, lo=0.0, lo_open=True, hi=1e6, doc="receptor gain (the paper: 1 V s)")
    h: float = param(0.0, lo=0.0, hi=1e6, doc="threshold (the paper: 0)")
    tau_s: float = param(0.3, lo=0.0, lo_open=True, hi=100.0, doc="s, window of Figs 4-5")
    tau_sweep_s: tuple[float, ...] = param((0.01, 0.03, 0.1, 0.3), lo=0.0, lo_open=True, hi=100.0, min_len=1,
                                           doc="s, windows of Fig 6")
    kernel: str = param("boxcar", choices=("boxcar", "exponential"), doc="temporal summation kernel")


@dataclass(frozen=True, kw_only=True)
class Scene:
    scene: Head
    skin: Skin = Skin()
    loading: Loading = Loading()
    steps: Steps = Steps()
    model: Model = Model()
    mesh: Mesh = Mesh()
    neuron: Neuron = Neuron()

    def check(self, path) -> None:
        """Cross-field rules: exact list lengths, a consistent geometry and mesh."""
        if len(self.skin.e_mpa) != 3:
            raise SceneError(path, "skin.e_mpa", f"needs exactly 3 moduli, got {len(self.skin.e_mpa)}")
        if len(self.skin.thickness_mm) != 2:
            raise SceneError(path, "skin.thickness_mm", f"needs exactly 2 thicknesses, got {len(self.skin.thickness_mm)}")
        from feeler.errors import ArgumentError
        from feeler.simulate.finger import mesh_spec_of, skin_params_of
        try:
            params = skin_params_of(self)
            mesh_spec_of(self).check(params)
        except ArgumentError as exc:
            key = exc.name if exc.name.startswith("mesh.") else f"skin.{exc.name}"
            raise SceneError(path, key, f"{exc.value!r}: {exc.allowed}") from None
        self._check_steps(path)

    def _check_steps(self, path) -> None:
        """Figs 3–6 need the finger to cross every step, two heights to fit Fig 5's line
        through, and steps small next to the press (see :data:`MAX_STEP_OF_PRESS`)."""
        st, ld = self.steps, self.loading
        if len(set(st.heights_um)) < 2:
            raise SceneError(path, "steps.heights_um", f"{list(st.heights_um)}: needs at least 2 distinct heights "
                                                       f"(Fig 5 fits a line of peak against height)")
        lo, hi = st.position_mm - st.edge_um * 5e-4, st.position_mm + st.edge_um * 5e-4
        if not (lo > 0.0 and hi < ld.slide_mm):
            raise SceneError(path, "steps.position_mm", f"{st.position_mm:g}: the step (its edge {lo:g} to {hi:g} mm) "
                                                        f"must lie inside the slide, 0 < x < loading.slide_mm = "
                                                        f"{ld.slide_mm:g} mm, so that the finger crosses it")
        limit_um = MAX_STEP_OF_PRESS * ld.press_mm * 1e3
        top = max(st.heights_um)
        if top > limit_um:
            raise SceneError(path, "steps.heights_um", f"{top:g} µm: at most {limit_um:g} µm, a tenth of the press depth "
                                                       f"loading.press_mm = {ld.press_mm:g} mm (the skin models are "
                                                       f"linear about the pressed state; beyond a tenth L1 departs "
                                                       f"from L2 and the step's strain is no longer small)")
