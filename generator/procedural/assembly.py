"""From part specifications (primitives, joint, handle, look) to an ``ArticulatedObject``.

Builders describe each part as a ``PartSpec``; ``assemble`` unions the primitives
into watertight meshes, paints them, names the movable parts ``<semantic>_<k>``
in a stable order (top to bottom, then left to right, i.e. descending z then
ascending y of the part's front) and records provenance.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

from generator.articulated import BASE, ArticulatedObject, Handle, Joint, Part, Primitive
from generator.procedural.appearance import Look, paint
from generator.procedural.solids import union_mesh


@dataclass
class PartSpec:
    """One part before meshing.

    ``accent[i]`` is the tone of ``primitives[i]`` (``generator.procedural.appearance``):
    False for the body colour, True for a trim (handle, knob) painted in the accent
    colour, 2, 3, .. for the look's further tones; ``order`` is (z, y) of the part's front centre (m), used for naming.
    """

    semantic: str
    material: str
    look: Look
    primitives: list[Primitive] = field(default_factory=list)
    accent: list[bool | int] = field(default_factory=list)
    joint: Joint | None = None
    handle: Handle | None = None
    order: tuple[float, float] = (0.0, 0.0)

    def add(self, prims: list[Primitive], accent: bool | int = False) -> None:
        self.primitives.extend(prims)
        self.accent.extend([accent] * len(prims))


def build_part(name: str, spec: PartSpec) -> Part:
    """Mesh, paint and wrap one ``PartSpec`` as a ``Part`` called ``name``."""
    mesh = union_mesh(spec.primitives)
    paint(mesh, spec.primitives, spec.accent, spec.look)
    return Part(
        name=name,
        semantic=spec.semantic,
        mesh=mesh,
        joint=spec.joint,
        primitives=list(spec.primitives),
        handle=spec.handle,
        material=spec.material,
    )


def assemble(
    category: str,
    base: PartSpec,
    movable: list[PartSpec],
    provenance: dict[str, Any],
) -> ArticulatedObject:
    """The metric ``ArticulatedObject`` made of ``base`` and the ``movable`` parts."""
    ordered = sorted(movable, key=lambda s: (-round(s.order[0], 4), round(s.order[1], 4)))
    counters: dict[str, int] = defaultdict(int)
    parts = [build_part(BASE, base)]
    for spec in ordered:
        k = counters[spec.semantic]
        counters[spec.semantic] += 1
        parts.append(build_part(f"{spec.semantic}_{k}", spec))
    return ArticulatedObject(parts=parts, category=category, scale=1.0, provenance=provenance)
