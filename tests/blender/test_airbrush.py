"""Airbrush particle step and Fill Mesh with Fog (addon/airlight/airbrush.py), headless.

Confinement is checked against the closed-form geometry of the test meshes (an axis-aligned
room and box, a UV sphere's inscribed radius), not against the code's own ray casts."""
import math

import bpy
import numpy as np
import pytest

from airlight import airbrush, fog_object as fo


@pytest.fixture
def scene():
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    return bpy.context.scene


def _box(scene, name, lo, hi, flip=False):
    """A closed axis-aligned box mesh [lo, hi] (normals inward when _flip_)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    if flip:
        faces = [tuple(reversed(f)) for f in faces]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(v, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def _run_particles(scene, origin, normal, steps=60, n=500, speed=4.0, diffusion=0.5, seed=3):
    bvh = airbrush.scene_bvh(bpy.context.evaluated_depsgraph_get())
    rng = np.random.default_rng(seed)
    p, v = airbrush.spawn(origin, normal, n, speed, rng)
    history = [p]
    for _ in range(steps):
        p, v = airbrush.step(p, v, 1.0 / 30.0, diffusion, 0.5, bvh, rng)
        history.append(p)
    return np.array(history)


def test01_spawn_directions_and_hemisphere():
    rng = np.random.default_rng(0)
    p, v = airbrush.spawn((1, 2, 3), None, 4000, 2.0, rng)
    assert np.allclose(p, (1, 2, 3)) and np.allclose(np.linalg.norm(v, axis=1), 2.0)
    assert np.abs(v.mean(0)).max() < 0.1  # isotropic
    _, v = airbrush.spawn((0, 0, 0), (0, 0, 1), 4000, 1.0, rng)
    assert (v[:, 2] >= 0).all() and abs(v[:, 2].mean() - 0.5) < 0.03  # uniform hemisphere


def test02_particles_stay_inside_a_room(scene):
    """A closed room [-2,2]x[-2,2]x[0,3]: particles shot fast from inside hit the walls many
    times and all stay inside it after every step."""
    _box(scene, "Room", (-2, -2, 0), (2, 2, 3), flip=True)
    history = _run_particles(scene, (0.0, 0.0, 1.5), None, speed=6.0)
    lo, hi = np.array([-2, -2, 0]), np.array([2, 2, 3])
    assert ((history >= lo) & (history <= hi)).all()
    # they did reach the walls (a free flight would end 6 m * ~1.6 s away)
    assert np.abs(history[-1]).max() > 1.9
    # and spread through the room rather than piling in one corner
    assert history[-1].std(0).min() > 0.5


def test03_no_particle_enters_a_closed_box(scene):
    """Shot at a solid box from outside: no particle ends inside its walls."""
    _box(scene, "Solid", (-1, -1, 0), (1, 1, 2))
    history = _run_particles(scene, (0.0, 0.0, 2.3), (0, 0, 1), speed=5.0, steps=60)
    # shoot downwards too: directions over the whole sphere
    history2 = _run_particles(scene, (0.0, -1.3, 1.0), None, speed=5.0, steps=60, seed=4)
    for h in (history, history2):
        inside = ((h > [-1, -1, 0]) & (h < [1, 1, 2])).all(axis=2)
        assert not inside.any(), f"{int(inside.sum())} particle positions inside the box"


def test04_no_surfaces_free_flight():
    rng = np.random.default_rng(1)
    p, v = airbrush.step(np.zeros((3, 3)), np.array([[1.0, 0, 0]] * 3), 0.5, 0.0, 0.0, None, rng)
    np.testing.assert_allclose(p, [[0.5, 0, 0]] * 3)


def test04b_mirror_bounce_off_a_floor(scene):
    """A move of (0.2, 0, -0.2) from 0.1 above a floor: it reaches the floor at x = 0.1 and
    the rest of the move and the velocity are mirrored (law of reflection)."""
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("Floor", mesh))
    bvh = airbrush.scene_bvh(bpy.context.evaluated_depsgraph_get())
    rng = np.random.default_rng(0)
    p, v = airbrush.step([[0.0, 0.0, 0.1]], [[0.2, 0.0, -0.2]], 1.0, 0.0, 0.0, bvh, rng)
    np.testing.assert_allclose(p, [[0.2, 0.0, 0.1]], atol=2e-4)
    np.testing.assert_allclose(v, [[0.2, 0.0, 0.2]], atol=1e-6)


def _uv_sphere(scene, radius=1.0, segments=48, rings=24):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, segments=segments, ring_count=rings,
                                         location=(0.5, -0.25, 1.0))
    return bpy.context.active_object


def test05_fill_mesh_inside_sphere_and_covers_it(scene):
    sphere = _uv_sphere(scene)
    fog = fo.new_fog_object("Fog", scene.collection, centres=[(9.0, 9.0, 9.0)], scales=1.0, amplitudes=0.1)
    settings = scene.airlight_airbrush
    settings.scale = 8.0
    settings.amplitude = 0.2
    settings.fill_spacing = 0.75
    for o in scene.objects:
        o.select_set(o in (sphere, fog))
    bpy.context.view_layer.objects.active = fog
    assert bpy.ops.airlight.fill_mesh() == {'FINISHED'}
    c, a, amp = fo.read(fog)
    c, a, amp = c[1:], a[1:], amp[1:]
    centre = np.array([0.5, -0.25, 1.0])
    h = 0.75 / 8.0
    r = np.linalg.norm(c - centre, axis=1)
    # the UV sphere's faces are at least r cos(pi/24) cos(pi/48)... from the centre: within 1
    assert r.max() < 1.0
    np.testing.assert_allclose(a, 8.0)
    np.testing.assert_allclose(amp, 0.2, rtol=1e-6)
    # covers it: every point of the inscribed ball is within half a cell diagonal of a centre
    rng = np.random.default_rng(0)
    q = rng.normal(size=(3000, 3))
    q = centre + q / np.linalg.norm(q, axis=1, keepdims=True) * (0.95 * np.cbrt(rng.random(3000)))[:, None]
    from mathutils.kdtree import KDTree
    tree = KDTree(len(c))
    for i, p in enumerate(c):
        tree.insert(p, i)
    tree.balance()
    nearest = np.array([tree.find(p)[2] for p in q])
    assert nearest.max() <= 0.5 * math.sqrt(3.0) * h + 1e-6
    # and the count matches the grid cells of the ball's volume
    expected = 4.0 / 3.0 * math.pi / h ** 3
    assert abs(len(c) - expected) < 0.06 * expected


def test06_fill_mesh_is_one_undoable_step_and_keeps_object_transform(scene):
    sphere = _uv_sphere(scene, radius=0.5)
    fog = fo.new_fog_object("Fog", scene.collection, centres=[(0.0, 0.0, 0.0)], scales=1.0,
                            amplitudes=0.1, location=(1.0, 0.0, 0.0))
    fog.scale = (2.0, 2.0, 2.0)
    scene.airlight_airbrush.scale = 10.0
    for o in scene.objects:
        o.select_set(o in (sphere, fog))
    bpy.context.view_layer.objects.active = fog
    assert bpy.ops.airlight.fill_mesh() == {'FINISHED'}
    g = fo.gather(bpy.context.evaluated_depsgraph_get())
    world, scales = g[0][1:], g[1][1:]
    assert (np.linalg.norm(world - [0.5, -0.25, 1.0], axis=1) < 0.5).all()
    np.testing.assert_allclose(scales, 10.0, rtol=1e-5)  # world a as set, object scale 2


def test07_fill_mesh_poll_needs_a_mesh_and_fog(scene):
    fog = fo.new_fog_object("Fog", scene.collection, centres=[(0.0, 0.0, 0.0)])
    bpy.context.view_layer.objects.active = fog
    fog.select_set(True)
    assert not bpy.ops.airlight.fill_mesh.poll()
    with pytest.raises(ValueError):
        airbrush.fill_points(None, (0, 0, 0), (100, 100, 100), 0.01, max_points=1000)


def test08_settings_have_tooltips_and_limits(scene):
    props = scene.airlight_airbrush.bl_rna.properties
    for p in props:
        if p.identifier in {"rna_type", "name"}:
            continue
        assert p.description, p.identifier
    settings = scene.airlight_airbrush
    settings.rate = 0.0
    settings.scale = -1.0
    assert settings.rate >= 1.0 and settings.scale > 0.0
