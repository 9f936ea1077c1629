"""UsdGeom.PointInstancer: each prototype prim (meshes and implicit gprims under each prototype
root) becomes one unit drawn at the instances that use that prototype, their transforms from USD
(ComputeInstanceTransformsAtTime) at each shutter time. An implicit sphere's instances are split by
the icosphere level their size on screen asks for (tessellate.sphere_levels): a field of particle
spheres is mostly small ones, and 1280 triangles each made 10 000 of them 12.8 M triangles."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from ..core.affine import invert_affine
from ..core.log import warn_once
from .tessellate import SPHERE_LEVEL_MAX, gprim_number, sphere_levels, sphere_radius_px, tessellate_gprim
from .units import FLAG_SMOOTH, GeomUnit, prototype_unit_name
from .values import array_value

#: implicit gprims a prototype may hold (tessellate.tessellate_gprim)
IMPLICIT = (UsdGeom.Cube, UsdGeom.Sphere, UsdGeom.Cylinder, UsdGeom.Cone, UsdGeom.Capsule, UsdGeom.Plane)


def add_instancer_units(scene, prim: Usd.Prim, t: Usd.TimeCode) -> None:
    """Units of PointInstancer `prim` at frame time t, added to `scene` (the usd.scene.Scene being
    built): one per prototype prim (and, for an implicit sphere, per icosphere level its instances
    take on screen), drawn at the instances of that prototype."""
    inst = UsdGeom.PointInstancer(prim)
    path = str(prim.GetPath())
    protos = inst.GetPrototypesRel().GetForwardedTargets()
    proto_indices = array_value(inst.GetProtoIndicesAttr(), t, np.int64)
    if len(proto_indices) == 0:
        return
    bad = proto_indices[(proto_indices < 0) | (proto_indices >= len(protos))]
    if len(bad):
        if scene._invalid(path, f"protoIndices hold {int(bad[0])}, outside the {len(protos)} prototypes"):
            return
    mask = inst.ComputeMaskAtTime(t)
    mask = np.ones(len(proto_indices), bool) if not mask or len(mask) != len(proto_indices) else np.asarray(mask, bool)
    base = scene.frame
    n_all = len(proto_indices)
    at_frame = inst.ComputeInstanceTransformsAtTime(t, t)
    if at_frame is None or len(at_frame) != n_all:   # USD refuses the instancer (its own diagnostic)
        if scene._invalid(path, f"USD cannot compute its {n_all} instance transforms at time {base:g} "
                               f"(positions, orientations or scales do not match protoIndices)"):
            return

    def all_transforms(time: float) -> np.ndarray:
        xf = inst.ComputeInstanceTransformsAtTime(Usd.TimeCode(time), Usd.TimeCode(base))
        if xf is None or len(xf) != n_all:
            warn_once(f"instcount:{path}", f"{path}: instance count changes over time; holding the frame's instances")
            xf = inst.ComputeInstanceTransformsAtTime(Usd.TimeCode(base), Usd.TimeCode(base))
        return np.array(xf, np.float64).reshape(-1, 4, 4)   # (Vt.Matrix4dArray's buffer: 20x a loop over its items)

    for pi, proto_path in enumerate(protos):
        sel = np.nonzero((proto_indices == pi) & mask)[0]
        proto_root = scene.stage.GetPrimAtPath(proto_path)
        if len(sel) == 0 or not proto_root:
            continue
        rng = iter(Usd.PrimRange(proto_root, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)))
        for sub in rng:
            if UsdGeom.Imageable(sub).ComputePurpose() in (UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide):
                rng.PruneChildren()
                continue
            if sub.IsA(UsdGeom.Mesh):
                topo = scene._mesh_topology(sub, t)
                if topo is None:
                    continue
                tris, face_of_tri, corners, npts, smooth = topo
                points_at = scene._points_fn(sub, npts)
            elif any(sub.IsA(c) for c in IMPLICIT):
                for level, level_sel in _instance_sphere_levels(scene, sub, proto_root, prim, sel, all_transforms):
                    out = tessellate_gprim(sub, t, level)
                    if out is None:
                        break
                    pts, tris, smooth, face_of_tri, corners = out
                    name = prototype_unit_name(path, proto_path, sub.GetPath())
                    if level != SPHERE_LEVEL_MAX:
                        name += f" level {level}"
                    _add_prototype_unit(scene, prim, proto_root, sub, t, level_sel, all_transforms, name, tris,
                                        len(pts), lambda time, p=pts: p, smooth, face_of_tri, corners)
                continue
            else:
                continue
            _add_prototype_unit(scene, prim, proto_root, sub, t, sel, all_transforms,
                                prototype_unit_name(path, proto_path, sub.GetPath()), tris, npts, points_at,
                                smooth, face_of_tri, corners)


def _prototype_to_instancer(cache: UsdGeom.XformCache, sub: Usd.Prim, root: Usd.Prim, instancer: Usd.Prim,
                            instance_xf: np.ndarray) -> np.ndarray:
    """(N, 4, 4) row-vector matrices taking prototype prim `sub` (under prototype root `root`)
    to world space through each instance transform instance_xf (N, 4, 4) of `instancer`."""
    sub_w = np.array(cache.GetLocalToWorldTransform(sub), np.float64)
    root_w = np.array(cache.GetLocalToWorldTransform(root), np.float64)
    inst_w = np.array(cache.GetLocalToWorldTransform(instancer), np.float64)
    sub_in_root = sub_w @ invert_affine(root_w)
    return sub_in_root[None] @ instance_xf @ inst_w[None]


def _instance_sphere_levels(scene, sub: Usd.Prim, root: Usd.Prim, instancer: Usd.Prim, sel: np.ndarray,
                            all_transforms) -> list[tuple[int, np.ndarray]]:
    """[(icosphere level, the instances of `sel` that take it)] for prototype prim `sub` of an
    instancer: an implicit sphere's instances by their size on screen at the frame time
    (tessellate.sphere_levels; a field of particle spheres is mostly small), any other gprim's
    all at SPHERE_LEVEL_MAX (unused there)."""
    if not sub.IsA(UsdGeom.Sphere) or scene.proj is None:
        return [(SPHERE_LEVEL_MAX, sel)]
    cache = scene._xf_cache(scene.frame)
    to_cam = _prototype_to_instancer(cache, sub, root, instancer, all_transforms(scene.frame)[sel]) \
        @ scene.cam_from_world(scene.frame)[None]
    radius = gprim_number(UsdGeom.Sphere(sub).GetRadiusAttr(), Usd.TimeCode(scene.frame))
    levels = sphere_levels(sphere_radius_px(scene.proj, to_cam, radius), scene.sphere_error_px)
    return [(int(level), sel[levels == level]) for level in np.unique(levels)]


def _add_prototype_unit(scene, instancer: Usd.Prim, root: Usd.Prim, sub: Usd.Prim, t: Usd.TimeCode,
                        sel: np.ndarray, all_transforms, name: str, tris: np.ndarray, npts: int, points_at,
                        smooth: bool, face_of_tri: np.ndarray, corners: np.ndarray | None) -> None:
    """One unit for prototype prim `sub` (triangles tris over npts points_at) drawn at instances
    `sel` of `instancer` (all_transforms(time): every instance's transform)."""
    if len(tris) == 0 or len(sel) == 0:
        return
    material, flags, blur = scene._common(sub, t)
    colors, uvs, opacity = scene._surface_primvars(sub, t, material, tris, face_of_tri, corners)
    flags |= FLAG_SMOOTH if smooth else 0

    def transforms_at(time: float, cache: UsdGeom.XformCache) -> np.ndarray:
        return _prototype_to_instancer(cache, sub, root, instancer, all_transforms(time)[sel])

    scene.units.append(GeomUnit(
        path=name, prim=sub, local_tris=tris, num_points=npts, points_at=points_at,
        transforms_at=transforms_at, num_instances=len(sel), corner_colors=colors, corner_uvs=uvs,
        material=material, flags=flags, blur_scale=blur, visibility_prims=[instancer, sub],
        corner_opacity=opacity))
