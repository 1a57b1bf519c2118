"""Gathering the plates in the sand, one compiled kernel per kind of surface.

Conventions: MuJoCo arrays are passed as the views mjData/mjModel expose (world frame,
z up, SI). A "sand body" is a body a scene names as touching sand; its plates are stored in
its body frame (`xpos`/`xmat`), grouped into spatial clusters of a few dozen plates with a
bounding sphere each (`clusters.cluster_plates`), so plates above the sand are skipped a
cluster at a time. A "slot" is a sand body with at least one plate in the sand this step; slots are
numbered 0..S-1 in the order bodies are visited, and a slot's plates are consecutive columns
of the gathered table (`layout`: rows NORMAL ... SPEED) with their RFT force for the current
direction of motion (`rft.kernel.leading_forces`).

The gather kernels (`gather_plane`, `gather_slope`, `gather_grid`, `gather_deformable`) are
one source, `_gather_plates`, compiled once per kind of surface with its globals KIND and
DEFORM bound to that surface's constants (`_gather_kernel`), so each compiles its own
surface's plate loop only. They are bound at the end of this module, once every function
their code calls is defined here or imported.
"""
import types

import numpy as np
from numba import njit

from ..kernel_cache import forget_stale
from ..rft.force_law import TANGENTIAL  # the leading rule, with the body's speed scale
from ..rft.kernel import leading_forces
from ..rft.law_rows import AREA, DIRECTION, NORMAL, NORMAL_SPEED, SCALE
from .table_readers import (float_matrix, float_vector, int8_matrix, int32_matrix, int32_vector,
                          int_matrix, int_vector)
from .deformable_codes import OUTSIDE
from .deformable_kernels import mark_cell, settle, touch_cell
from .layout import (BASE_INV_DX, BASE_INV_DY, BASE_KIND, BASE_X0, BASE_Y0, DEFORM_RISE,
                     DYNAMIC, GATHER, GATHERED, GRID_INV_DX, GRID_INV_DY, GRID_X0, GRID_Y0,
                     INV_A4, INV_B4, LEADING, LEVER, MAP_INV_DX, MAP_INV_DY, MAP_X0, MAP_Y0,
                     MOMENT, SLOPE_X, SLOPE_Y, SLOTS, SPEED, STEPS, SURFACE, TILE_STEP,
                     TRAILING, ZETA, ZETA_MAP)
from .surface import FLAT, GRID, SLOPE
from .surface_kernels import (base_height, bed_range, cell_height, grid_range, inside_grid,
                              map_factor, node_height, plane_top, surface_range,
                              tile_plane, window_range)


#: The kind of surface (surface.FLAT, SLOPE or GRID) and whether it is deformable sand, of a
#: gather kernel: `_gather_plates` reads them as globals, which each kernel binds to its own
#: constants (`_gather_kernel`). None here: `_gather_plates` itself is never run.
KIND = DEFORM = None


def _gather_plates(arrays):
    """Find the plates in the sand and their RFT force for the current direction of motion:
    one step (counted in the STEPS counter); on deformable sand, then rules 2-4 for the
    footprints the bodies left in this step (`deformable_kernels.settle`). KIND (surface.FLAT, SLOPE
    or GRID) and DEFORM (deformable sand: a GRID) are constants each gather kernel binds
    (`_gather_kernel`), so that each kind of surface runs a plate loop of its own.

    arrays: the table of an `ArrayTable` of `GatherArrays`; settings SURFACE ... TRAILING.

    Bodies whose bounding sphere (radius `radii`, about the body origin), and then clusters
    whose bounding sphere, lies above the surface (above its highest point within the
    sphere's radius, horizontally) are skipped without touching their plates. A plate's
    depth is the surface height at its (x, y) minus its z (vertical, world axes): a
    horizontal plane (FLAT) keeps the original arithmetic, bit for bit, and so
    does a grid level under the cluster (its lowest node there == its highest: every
    bilinear height there is that level exactly; where the blocks are level under the body's
    whole sphere, its clusters are not bounded one by one); elsewhere on a grid only plates
    below the highest node under the cluster read the grid (a body a cell inside the grid
    all round without clamping: `inside_grid`, in a plate loop of its own: `_grid_cluster`).
    The nodes under a cluster are bounded on a rigid grid by the window from the first node
    of the cluster's square (`window_range`), on deformable sand by its blocks; or, on a
    rigid grid near a plane around the body (its tile's raised plane, `tile_plane`; a level
    tile has none), the plates below that plane's highest point over the cluster read the
    grid, the body itself bounded by that plane's highest point over its square instead of
    the blocks. On deformable sand
    (DEFORM) the plates below the surface mark their footprint cells
    (`deformable_kernels.mark_cell`), and the footprints the bodies left are settled after the
    plates are gathered (`gather_deformable`); beyond the bed its base (plane, slope or
    grid: `_deformable_base`) gives the depth, and bounds the bodies and clusters that reach
    out there, and a plate there marks nothing.
    positions, normals: (N, 3) body-frame plate positions l and normals n_l (separate, so
    that the depth test reads positions only). A plate below the surface first has
    n . v = n_l . (V + W x l) with the body-frame velocity V of the body origin and angular
    velocity W (9 multiply-adds), so only leading plates (n . v > TANGENTIAL x the body's
    speed scale), or all plates below the surface with TRAILING, are transformed to the
    world. Where a rigid grid is read (not level under the cluster), that motion test comes
    before the depth, being cheaper than a bilinear look-up: a trailing plate is dropped
    without one (the plates gathered are the same).
    With a zeta map (ZETA_MAP), a plate's zeta is multiplied by the map's factor at its (x, y).
    For each, column k of `table` (rows: kernel's NORMAL ... DIRECTION, then MOMENT, LEVER,
    SPEED; a trailing plate has SCALE and AREA 0, so it feels no force), out_plate[k] (plate
    index), out_slot[k] (slot) and the RFT force force[:3, k] (N, world). Counts the plates
    written, of those leading, and the slots S (counters GATHERED, LEADING, SLOTS);
    slot_body[s] is the slot's sand-body index, and its plates are columns slot_start[s] ..
    slot_start[s+1]-1.
    """
    a = GATHER
    settings, counters = float_vector(arrays, a.settings), int_vector(arrays, a.counters)
    surface_height, zeta_si = settings[SURFACE], settings[ZETA]
    include_trailing = settings[TRAILING] != 0.0
    flat, slope = KIND == FLAT, KIND == SLOPE
    gx, gy = settings[SLOPE_X], settings[SLOPE_Y]
    g_norm = np.sqrt(gx * gx + gy * gy)
    gx0, gy0 = settings[GRID_X0], settings[GRID_Y0]
    g_idx, g_idy = settings[GRID_INV_DX], settings[GRID_INV_DY]
    grid = float_matrix(arrays, a.surface_grid)
    block_max = float_matrix(arrays, a.surface_block_max)
    block_min = float_matrix(arrays, a.surface_block_min)
    tiles, tile_step = float_matrix(arrays, a.surface_tiles), np.int64(settings[TILE_STEP])
    window_max = float_matrix(arrays, a.surface_window_max)
    window_min = float_matrix(arrays, a.surface_window_min)
    zeta_map = settings[ZETA_MAP] != 0.0
    factors = float_matrix(arrays, a.zeta_factors)
    mx0, my0 = settings[MAP_X0], settings[MAP_Y0]
    m_idx, m_idy = settings[MAP_INV_DX], settings[MAP_INV_DY]
    deform_state = int_vector(arrays, a.deform_state)
    footprints = (int_matrix(arrays, a.deform_stamp), float_matrix(arrays, a.deform_lowest),
                  int_vector(arrays, a.deform_pending), deform_state,
                  int_matrix(arrays, a.deform_cell_stamp), float_matrix(arrays, a.deform_cell_low))
    bed_u, bed_v = grid.shape[1] - 1.0, grid.shape[0] - 1.0  # deformable sand: the bed's
    # last node coordinates; beyond them its base (`_deformable_base`)
    step = counters[STEPS]
    body_ids, radii = int_vector(arrays, a.body_ids), float_vector(arrays, a.radii)
    body_cluster_start = int_vector(arrays, a.body_cluster_start)
    cluster_plate_start = int_vector(arrays, a.cluster_plate_start)
    cluster_center = float_matrix(arrays, a.cluster_center)
    cluster_radius = float_vector(arrays, a.cluster_radius)
    positions, normals = float_matrix(arrays, a.positions), float_matrix(arrays, a.normals)
    areas = float_vector(arrays, a.areas)
    xpos, xmat = float_matrix(arrays, a.xpos), float_matrix(arrays, a.xmat)
    xipos, cvel = float_matrix(arrays, a.xipos), float_matrix(arrays, a.cvel)
    subtree_com = float_matrix(arrays, a.subtree_com)
    body_rootid = int32_vector(arrays, a.body_rootid)
    out_plate, out_slot = int_vector(arrays, a.out_plate), int_vector(arrays, a.out_slot)
    slot_body, slot_start = int_vector(arrays, a.slot_body), int_vector(arrays, a.slot_start)
    table = float_matrix(arrays, a.table)
    force = float_matrix(arrays, a.force)
    law = (zeta_si, areas, zeta_map, factors, mx0, my0, m_idx, m_idy, out_plate)
    k = np.int64(0)  # (typed, not Literal[int](0): that compiled the calls below twice)
    px = py = 0.0  # a plate's world x, y (m), as the depth on a grid needs them
    leading_count = 0
    slots = 0
    for i in range(body_ids.shape[0]):
        b = body_ids[i]
        # a grid reaching a cell beyond the body's sphere all round: its plates are looked
        # up unclamped; on deformable sand, otherwise they may lie beyond the bed (its base)
        inside = KIND == GRID and inside_grid(grid, gx0, gy0, g_idx, g_idy, xpos[b, 0],
                                              xpos[b, 1], radii[i])
        off_bed = DEFORM and not inside
        # a rigid grid near a plane (not level) around the body: that plane bounds it over the
        # body's square (its tile's: `tile_plane`), without reading the blocks there
        planar, p_a, p_gx, p_gy = False, 0.0, 0.0, 0.0
        if KIND == GRID and not DEFORM and inside and tile_step > 0:
            planar, p_a, p_gx, p_gy = tile_plane(tiles, tile_step, grid.shape[1], gx0, gy0,
                                                 g_idx, g_idy, xpos[b, 0], xpos[b, 1], radii[i])
        if planar:
            body_low = -np.inf  # (not level: the grid is read)
            body_top = plane_top(p_a, p_gx, p_gy, xpos[b, 0], xpos[b, 1], radii[i])
        elif DEFORM:
            body_low, body_top = bed_range(grid, block_max, block_min, gx0, gy0, g_idx, g_idy,
                                           xpos[b, 0], xpos[b, 1], radii[i],
                                           _deformable_base(arrays))
        else:
            body_low, body_top = surface_range(KIND, surface_height, gx, gy, g_norm, grid,
                                               block_max, block_min, gx0, gy0, g_idx, g_idy,
                                               xpos[b, 0], xpos[b, 1], radii[i])
        if xpos[b, 2] - radii[i] >= body_top:
            continue
        top = body_top
        first = k
        root = body_rootid[b]
        ox, oy, oz = xpos[b, 0], xpos[b, 1], xpos[b, 2]
        r00, r01, r02 = xmat[b, 0], xmat[b, 1], xmat[b, 2]
        r10, r11, r12 = xmat[b, 3], xmat[b, 4], xmat[b, 5]
        r20, r21, r22 = xmat[b, 6], xmat[b, 7], xmat[b, 8]
        # cvel = [omega; velocity of the point at the root's subtree com], world
        wx, wy, wz = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        cx, cy, cz = subtree_com[root, 0], subtree_com[root, 1], subtree_com[root, 2]
        vcx, vcy, vcz = cvel[b, 3], cvel[b, 4], cvel[b, 5]
        comx, comy, comz = xipos[b, 0], xipos[b, 1], xipos[b, 2]
        rotation = (r00, r01, r02, r10, r11, r12, r20, r21, r22)
        motion = (cx, cy, cz, vcx, vcy, vcz, wx, wy, wz, comx, comy, comz)
        vx0 = vcx + wy * (oz - cz) - wz * (oy - cy)  # velocity of the body origin
        vy0 = vcy + wz * (ox - cx) - wx * (oz - cz)
        vz0 = vcz + wx * (oy - cy) - wy * (ox - cx)
        body_v = (r00 * vx0 + r10 * vy0 + r20 * vz0, r01 * vx0 + r11 * vy0 + r21 * vz0,
                  r02 * vx0 + r12 * vy0 + r22 * vz0)
        body_w = (r00 * wx + r10 * wy + r20 * wz, r01 * wx + r11 * wy + r21 * wz,
                  r02 * wx + r12 * wy + r22 * wz)
        tangential = TANGENTIAL * (np.sqrt(vx0 * vx0 + vy0 * vy0 + vz0 * vz0)
                                   + radii[i] * np.sqrt(wx * wx + wy * wy + wz * wz))
        # a slope's depth is linear in the body-frame position: surface_height minus
        # (z - gx x - gy y) = s_0 + s . l
        s_0 = oz - gx * ox - gy * oy
        s_x, s_y = r20 - gx * r00 - gy * r10, r21 - gx * r01 - gy * r11
        s_z = r22 - gx * r02 - gy * r12
        for c in range(body_cluster_start[i], body_cluster_start[i + 1]):
            ccx, ccy, ccz = cluster_center[c, 0], cluster_center[c, 1], cluster_center[c, 2]
            # the surface under the cluster: level at `level`, or (lookup) a grid to read
            level, lookup = surface_height, False
            if slope:
                if (s_0 + s_x * ccx + s_y * ccy + s_z * ccz - cluster_radius[c]
                        >= surface_height + cluster_radius[c] * g_norm):
                    continue
            else:
                bottom = oz + r20 * ccx + r21 * ccy + r22 * ccz - cluster_radius[c]
                if flat or body_low == body_top:  # level under the body: under the cluster
                    level = body_top
                else:
                    if bottom >= body_top:  # (above the body's bound: nothing to read)
                        continue
                    wx_c = ox + r00 * ccx + r01 * ccy + r02 * ccz  # the cluster's centre
                    wy_c = oy + r10 * ccx + r11 * ccy + r12 * ccz
                    if planar:  # the body's tile plane, at its highest over the cluster
                        top = plane_top(p_a, p_gx, p_gy, wx_c, wy_c, cluster_radius[c])
                        low = -np.inf  # (not level: the grid is read)
                    elif not DEFORM:  # a rigid grid: the window over the cluster
                        low, top = window_range(window_max, window_min, gx0, gy0, g_idx,
                                                g_idy, wx_c, wy_c, cluster_radius[c])
                    elif off_bed:  # (deformable sand, a body reaching beyond the bed)
                        low, top = bed_range(grid, block_max, block_min, gx0, gy0, g_idx,
                                             g_idy, wx_c, wy_c, cluster_radius[c],
                                             _deformable_base(arrays))
                    else:
                        low, top = grid_range(grid, block_max, block_min, gx0, gy0, g_idx,
                                              g_idy, wx_c, wy_c, cluster_radius[c])
                    level, lookup = top, low != top
                if bottom >= top:
                    continue
            j0 = cluster_plate_start[c]
            j1 = cluster_plate_start[c + 1]
            cluster, cluster_normals = positions[j0:j1], normals[j0:j1]  # (no wraparound)
            if KIND == GRID and lookup and inside:  # (the grids' common case)
                k, leading_count = _grid_cluster(
                    DEFORM, j0, cluster, cluster_normals, (ox, oy, oz), rotation, top,
                    (body_v, body_w, tangential, include_trailing), (grid, gx0, gy0, g_idx,
                    g_idy), (footprints, step), motion, law, table, out_slot, slots, k,
                    leading_count)
                continue
            plain = not (slope or lookup or DEFORM)  # a plane, or a rigid grid level here
            # a rigid grid read here: the motion test (cheaper than a look-up) comes first
            motion_first = KIND == GRID and lookup and not DEFORM
            for i_c in range(cluster.shape[0]):
                lx, ly, lz = cluster[i_c, 0], cluster[i_c, 1], cluster[i_c, 2]
                pz = oz + r20 * lx + r21 * ly + r22 * lz
                n_v = 0.0
                if motion_first:
                    if pz >= top:  # above the highest node under the cluster
                        continue
                    n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
                    if not (n_v > tangential or include_trailing):
                        continue
                if plain:
                    depth = level - pz
                elif slope:
                    depth = surface_height - (s_0 + s_x * lx + s_y * ly + s_z * lz)
                elif lookup and pz >= top:  # above the highest node under the cluster
                    continue
                else:  # a grid, at the plate's node coordinates (u, v)
                    px = ox + r00 * lx + r01 * ly + r02 * lz
                    py = oy + r10 * lx + r11 * ly + r12 * lz
                    u, v = (px - gx0) * g_idx, (py - gy0) * g_idy
                    if inside:  # (level here: a grid read is `_grid_cluster`'s)
                        depth = level - pz
                        if DEFORM and depth > 0.0:
                            mark_cell(footprints, step, int(u), int(v), pz)
                    elif off_bed and (u < 0.0 or v < 0.0 or u > bed_u or v > bed_v):
                        # beyond the bed: its base, where a plate leaves no footprint
                        depth = (base_height(_deformable_base(arrays), px, py) if lookup
                                 else level) - pz
                        deform_state[OUTSIDE] += depth > 0.0
                    else:
                        depth = (node_height(grid, u, v) if lookup else level) - pz
                        if DEFORM and depth > 0.0:
                            touch_cell(footprints, step, u, v, pz)
                if depth <= 0.0:
                    continue
                if not motion_first:
                    n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
                leading = n_v > tangential
                if not (leading or include_trailing):
                    continue
                if plain or slope:  # (a grid's: above)
                    px = ox + r00 * lx + r01 * ly + r02 * lz
                    py = oy + r10 * lx + r11 * ly + r12 * lz
                _write_plate(table, k, cluster_normals, i_c, rotation, motion, law, px, py, pz,
                             n_v, depth, j0 + i_c, leading)
                out_slot[k] = slots
                leading_count += leading
                k += 1
        if k > first:
            slot_body[slots] = i
            slot_start[slots] = first
            slots += 1
    slot_start[slots] = k
    _directions(k, table)
    leading_forces(k, table, settings[INV_A4], settings[INV_B4], settings[DYNAMIC], force[0],
                   force[1], force[2])
    counters[STEPS] += 1
    counters[GATHERED], counters[LEADING], counters[SLOTS] = k, leading_count, slots
    if DEFORM:  # rules 2-4 for the footprints the bodies left in this step
        settle(float_matrix(arrays, a.surface_grid), float_matrix(arrays, a.surface_block_max),
               float_matrix(arrays, a.surface_block_min), int_matrix(arrays, a.deform_stamp),
               float_matrix(arrays, a.deform_lowest), int_vector(arrays, a.deform_pending),
               int_vector(arrays, a.deform_state), int_vector(arrays, a.deform_committed),
               float_vector(arrays, a.deform_amount), int_vector(arrays, a.deform_queue),
               int8_matrix(arrays, a.deform_in_queue), int8_matrix(arrays, a.deform_dirty),
               int_vector(arrays, a.deform_dirty_list), int_matrix(arrays, a.deform_changed),
               int32_matrix(arrays, a.deform_distance), int_vector(arrays, a.deform_reached),
               int_vector(arrays, a.counters)[STEPS] - 1,
               float_vector(arrays, a.settings)[DEFORM_RISE])


@njit(inline='always')
def _grid_cluster(deform, j0, cluster, cluster_normals, origin, rotation, top, test, surface,
                  marks, motion, law, table, out_slot, slots, k, leading_count):
    """The plates of one cluster (plate j0 its first) of a body a cell inside a grid that is
    read under the cluster (`_gather_plates`' common case on grids, with the loop's other
    cases left out): plates below `top` (m), on a rigid grid leading ones first (the motion
    test before the look-up), on deformable sand (`deform`) marking their footprint cells.
    origin, rotation: the body's pose; test: (body_v, body_w, tangential, include_trailing);
    surface: (grid, x0, y0, 1/dx, 1/dy); marks: (footprints, step). Returns k and
    leading_count, advanced."""
    ox, oy, oz = origin
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation
    body_v, body_w, tangential, include_trailing = test
    grid, gx0, gy0, g_idx, g_idy = surface
    footprints, step = marks
    for i_c in range(cluster.shape[0]):
        lx, ly, lz = cluster[i_c, 0], cluster[i_c, 1], cluster[i_c, 2]
        pz = oz + r20 * lx + r21 * ly + r22 * lz
        if pz >= top:  # above the highest node under the cluster
            continue
        n_v = 0.0
        if not deform:  # the motion test first: it is cheaper than a look-up
            n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
            if not (n_v > tangential or include_trailing):
                continue
        px = ox + r00 * lx + r01 * ly + r02 * lz
        py = oy + r10 * lx + r11 * ly + r12 * lz
        u, v = (px - gx0) * g_idx, (py - gy0) * g_idy
        i_u, i_v = int(u), int(v)  # (1 <= u <= nx - 2, likewise v)
        depth = cell_height(grid, i_u, i_v, u - i_u, v - i_v) - pz
        if depth <= 0.0:
            continue
        if deform:  # a trailing plate in the sand leaves a footprint too
            mark_cell(footprints, step, i_u, i_v, pz)
            n_v = _normal_speed(cluster_normals, i_c, body_v, body_w, lx, ly, lz)
        leading = n_v > tangential
        if not (leading or include_trailing):
            continue
        _write_plate(table, k, cluster_normals, i_c, rotation, motion, law, px, py, pz,
                     n_v, depth, j0 + i_c, leading)
        out_slot[k] = slots
        leading_count += leading
        k += 1
    return k, leading_count


@njit(inline='always')
def _write_plate(table, k, normals, i, rotation, motion, law, px, py, pz, n_v, depth, j,
                 leading):
    """Column k of the gathered table for plate j (i of `normals`, body frame) in the sand at
    world (px, py, pz), depth `depth` (m), normal speed n_v (`_gather_plates`)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation
    cx, cy, cz, vcx, vcy, vcz, wx, wy, wz, comx, comy, comz = motion
    zeta_si, areas, zeta_map, factors, mx0, my0, m_idx, m_idy, out_plate = law
    mx, my, mz = normals[i, 0], normals[i, 1], normals[i, 2]
    rx, ry, rz = px - cx, py - cy, pz - cz
    table[DIRECTION, k] = vcx + wy * rz - wz * ry  # v, made d by _directions
    table[DIRECTION + 1, k] = vcy + wz * rx - wx * rz
    table[DIRECTION + 2, k] = vcz + wx * ry - wy * rx
    table[LEVER, k], table[LEVER + 1, k] = px - comx, py - comy
    table[LEVER + 2, k] = pz - comz
    table[NORMAL, k] = r00 * mx + r01 * my + r02 * mz
    table[NORMAL + 1, k] = r10 * mx + r11 * my + r12 * mz
    table[NORMAL + 2, k] = r20 * mx + r21 * my + r22 * mz
    table[NORMAL_SPEED, k] = n_v
    scale = zeta_si * depth * areas[j]
    if zeta_map:
        scale *= map_factor(factors, mx0, my0, m_idx, m_idy, px, py)
    table[SCALE, k] = scale if leading else 0.0
    table[AREA, k] = areas[j] if leading else 0.0
    out_plate[k] = j


@njit(inline='always')
def _deformable_base(arrays):
    """Deformable sand's base beyond the bed (`surface_kernels.base_height`), from the gather
    table's settings (BASE_KIND; SURFACE, SLOPE_X, SLOPE_Y; BASE_X0 ...) and base arrays."""
    a = GATHER
    settings = float_vector(arrays, a.settings)
    gx, gy = settings[SLOPE_X], settings[SLOPE_Y]
    return (np.int64(settings[BASE_KIND]), settings[SURFACE], gx, gy, np.sqrt(gx * gx + gy * gy),
            float_matrix(arrays, a.base_grid), float_matrix(arrays, a.base_block_max),
            float_matrix(arrays, a.base_block_min), settings[BASE_X0], settings[BASE_Y0],
            settings[BASE_INV_DX], settings[BASE_INV_DY])


@njit(inline='always')
def _normal_speed(normals, i, body_v, body_w, lx, ly, lz):
    """n . v of plate i at body-frame position l = (lx, ly, lz) with body-frame normal
    normals[i], for the body-frame velocity V of the body origin and angular velocity W:
    n . (V + W x l), m/s."""
    mx, my, mz = normals[i, 0], normals[i, 1], normals[i, 2]
    return (mx * (body_v[0] + body_w[1] * lz - body_w[2] * ly)
            + my * (body_v[1] + body_w[2] * lx - body_w[0] * lz)
            + mz * (body_v[2] + body_w[0] * ly - body_w[1] * lx))


def _gather_kernel(name, kind, deform, doc):
    """The compiled `_gather_plates` of a surface of kind `kind` (deformable sand where
    `deform`), named `name`, documented by `doc`: the same code with its globals KIND and
    DEFORM bound to these constants. numba prunes the branches of the other surfaces before
    it types the code (its dead-branch pruning sees module constants, not argument values),
    so each kernel compiles its own surface's loop only: gather_plane took 9 s CPU to compile
    this way on an AMD EPYC VM, against 50 s as an inline='always' function called with
    constant arguments (numba's inliner copies a callee's whole scope once per block of it)
    and 37 s as a function compiled for literal arguments (no pruning); docs/speed.md."""
    function = types.FunctionType(_gather_plates.__code__,
                                  dict(globals(), KIND=kind, DEFORM=deform), name)
    function.__qualname__, function.__doc__ = name, doc
    return njit(cache=True, error_model='numpy', fastmath={'contract'})(function)


@njit(cache=True, error_model='numpy', fastmath=True)
def _directions(k, table):
    """Rows DIRECTION, MOMENT and SPEED of the plate table from the plates' world velocity
    v (in rows DIRECTION, replaced) and lever arm r (rows LEVER): d = v/|v| (0 at rest),
    r x d, |v|. One vectorised pass."""
    for j in range(k):
        vx, vy, vz = table[DIRECTION, j], table[DIRECTION + 1, j], table[DIRECTION + 2, j]
        rx, ry, rz = table[LEVER, j], table[LEVER + 1, j], table[LEVER + 2, j]
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        inv = 1.0 / speed if speed > 0.0 else 0.0
        dx, dy, dz = vx * inv, vy * inv, vz * inv
        table[DIRECTION, j], table[DIRECTION + 1, j], table[DIRECTION + 2, j] = dx, dy, dz
        table[MOMENT, j] = ry * dz - rz * dy
        table[MOMENT + 1, j] = rz * dx - rx * dz
        table[MOMENT + 2, j] = rx * dy - ry * dx
        table[SPEED, j] = speed


# The gather kernels, bound once every function their code calls is defined (`_gather_kernel`
# copies the module's globals).
gather_plane = _gather_kernel('gather_plane', FLAT, False,
                              '`_gather_plates` on a horizontal plane.')
gather_slope = _gather_kernel('gather_slope', SLOPE, False,
                              '`_gather_plates` on an inclined plane.')
gather_grid = _gather_kernel('gather_grid', GRID, False,
                             '`_gather_plates` on a rigid height grid.')
gather_deformable = _gather_kernel(
    'gather_deformable', GRID, True,
    '`_gather_plates` on deformable sand (a height grid the plates mark), then rules 2-4 for '
    'the footprints the bodies left in this step (`deformable_kernels.settle`): one call.')

forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
