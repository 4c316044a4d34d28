#
# SPDX-FileCopyrightText: Copyright (c) 2021-2026 NVIDIA CORPORATION & AFFILIATES. All rights reserved.
# SPDX-License-Identifier: Apache-2.0
#
"""
Deterministic generator of paths candidates using ray shooting and bouncing.

veriloc-rt: a copy of ``sionna/rt/path_solvers/sb_deterministic.py`` of sionna-rt 2.2.0
(pyproject.toml pins 2.2; Apache-2.0, header above) in which every integer that depends on the call's
target count (its index arithmetic, the per-source path budget, the buffer size, the last
element read of a prefix sum) reaches Dr.Jit as an opaque value instead of a literal compiled
into the kernels. Integer arithmetic gives the same integers either way: the candidates are
the same to the bit; the kernels no longer depend on the target count, so a new drive reuses
them (docs/performance.md, "Cold start"). Lines changed are marked ``# opaque``, and in
the index functions at the end every ``mi.UInt32(n)`` of a Python integer became ``_u32(n)``.
Regenerate it from a new Sionna RT with the changes listed; tests/unit/propagation checks
it against Sionna's own generator.
"""
from __future__ import annotations

from typing import Tuple, List

import drjit as dr
import mitsuba as mi

from sionna.rt.constants import InteractionType, MIN_SEGMENT_LENGTH
from sionna.rt.utils import spawn_ray_from_sources, fibonacci_lattice,\
    hash_fnv1a, spawn_ray_to, SourceExclusionBoxes
from sionna.rt.path_solvers.paths_buffer import PathsBuffer
from sionna.rt.path_solvers.sample_data import SampleData, source_index_per_sample
from sionna.rt.path_solvers.sb_candidate_generator import SBCandidateGenerator


def _u32(value) -> mi.UInt32:
    """``value`` as an opaque UInt32 (evaluated data, not a literal in the kernel)."""  # opaque
    return dr.opaque(mi.UInt32, value)


def _last(x: mi.UInt32) -> int:
    """The last element of ``x``, read at an opaque index."""  # opaque
    last = dr.gather(mi.UInt32, x, _u32(dr.width(x) - 1))
    dr.eval(last)
    return int(last[0])


UINT32_MAX = 0xFFFFFFFF
NON_SPECULAR_PATH_MARKER = UINT32_MAX - 1
NO_PATH_RECORDED_MARKER = UINT32_MAX - 2


class OpaqueSBDeterministicCandidateGenerator(SBCandidateGenerator):
    """
    Variant of the :class:`~sionna.rt.SBCandidateGenerator` class,
    implementing a deterministic version of the candidate generator algorithm,
    at the expense of a larger memory footprint.
    """

    def _los(self,
             mi_scene: mi.Scene,
             src_positions: mi.Point3f,
             tgt_positions: mi.Point3f,
             paths: PathsBuffer,
             paths_counter_per_source: mi.UInt,
             src_boxes: SourceExclusionBoxes | None = None):
        # pylint: disable=line-too-long
        """
        Tests line-of-sight (LoS) paths and add non-obstructed ones to the
        buffer

        The buffer ``paths`` is updated in-place.

        :param mi_scene: Mitsuba scene
        :param src_positions: Positions of the sources
        :param tgt_positions: Positions of the targets
        :param paths: Paths buffer. Updated in-place.
        :param paths_counter_per_source: Counts the number of paths found for each source
        :param src_boxes: Boxes which do not occlude the rays spawned from their source, one per source
        """

        num_src = dr.width(src_positions)
        num_tgt = dr.width(tgt_positions)

        # Sample data
        samples_data = SampleData(num_src, num_tgt, 0, diffraction=False)
        lane = dr.arange(mi.UInt32, num_src * num_tgt)       # opaque
        samples_data._src_indices = mi.UInt(lane // _u32(num_tgt))  # opaque

        # Target indices
        tgt_indices = mi.UInt(lane % _u32(num_tgt))          # opaque

        # Rays origins and targets
        origins = dr.gather(mi.Point3f, src_positions, lane // _u32(num_tgt))  # opaque
        targets = dr.gather(mi.Point3f, tgt_positions, lane % _u32(num_tgt))   # opaque

        # Discard LoS paths when sources and targets overlap
        length = dr.norm(targets - origins)
        valid = length > MIN_SEGMENT_LENGTH

        # Move the ray origins out of the boxes which do not occlude them.
        # The origin of a ray whose target lies within its box is left
        # untouched, as the advanced origin would lie beyond that target. Such
        # a ray is tested for occlusion over its whole length, so that the
        # geometry of the object the box stands for, which may be far from
        # filling it, does occlude it.
        if src_boxes is not None:
            advanced, advance = src_boxes.advance(
                origins, (targets - origins)*dr.rcp(length),
                samples_data.src_indices)
            origins = dr.select(advance < length, advanced, origins)

        # Test LoS
        rays = spawn_ray_to(origins, targets)
        valid &= ~mi_scene.ray_test(rays, active=valid)

        # Assign output offsets in source-major, target-minor lane order.
        output_indicator = dr.select(valid, mi.UInt32(1), mi.UInt32(0))
        output_offset = dr.prefix_reduce(dr.ReduceOp.Add, output_indicator,
                                         exclusive=False)
        num_new_paths = _last(output_offset)  # opaque
        output_offset = paths.paths_counter + (output_offset - 1)
        store = valid & (output_offset < _u32(paths.buffer_size))  # opaque

        # Store the paths
        paths.add_paths(mi.UInt(0), output_offset, samples_data, valid,
                        tgt_indices, rays.d, -rays.d, store)
        paths.advance_paths_counter(
            min(
                _u32(paths.buffer_size) - paths.paths_counter,  # opaque
                dr.opaque(mi.UInt32, num_new_paths),
            )
        )
        # Increment the sources counters
        dr.scatter_inc(paths_counter_per_source, samples_data.src_indices,
                       store)


    def _shoot_and_bounce(
        self,
        mi_scene: mi.Scene,
        src_positions: mi.Point3f,
        tgt_positions: mi.Point3f,
        paths: PathsBuffer,
        samples_per_src: int,
        max_num_paths_per_src: int,
        max_depth: int,
        paths_counter_per_source: mi.UInt,
        specular_reflection: bool,
        diffuse_reflection: bool,
        refraction: bool,
        diffraction: bool,
        edge_diffraction: bool,
        seed: int,
        src_boxes: SourceExclusionBoxes | None = None,
    ):
        loop_args = (
            mi_scene,
            src_positions,
            tgt_positions,
            samples_per_src,
            max_num_paths_per_src,
            max_depth,
            paths,
            paths_counter_per_source,
            specular_reflection,
            diffuse_reflection,
            refraction,
            diffraction,
            edge_diffraction,
        )

        num_sources = dr.width(src_positions)
        num_samples = samples_per_src * num_sources
        num_targets = dr.width(tgt_positions)

        ########################################################################
        # Step 1: count the number of paths that would be generated by each
        # thread.
        ########################################################################
        self._sampler.seed(seed, num_samples)
        with dr.scoped_set_flag(dr.JitFlag.OptimizeLoops, False):
            candidate_hashes, min_thread_index_per_hash = (
                self._shoot_and_bounce_loop(
                    *loop_args,
                    self._sampler,
                    counting_mode=True,
                    src_boxes=src_boxes,
                )
            )

        ########################################################################
        # Step 2: derive a deterministic ordering of the paths
        ########################################################################
        # For each output flag, check that the thread that claimed it
        # actually won the race. We need this check because of the running
        # atomic min reduction: a lower-index thread may always arrive later.
        # Layout matches `current_path_i` in `_shoot_and_bounce_loop`: target is
        # the fastest index, then thread, then depth.
        lane = dr.arange(mi.UInt32, max_depth * num_samples * num_targets)
        expected_thread_idx = \
            (lane // _u32(num_targets)) % _u32(num_samples)  # opaque
        assert dr.width(expected_thread_idx) == dr.width(candidate_hashes)

        hash0, hash1 = extract_hashes_from_u64(candidate_hashes)
        is_non_specular = candidate_hashes == NON_SPECULAR_PATH_MARKER
        did_win = (candidate_hashes != NO_PATH_RECORDED_MARKER) & (
            ~is_non_specular
        )
        did_win &= (
            dr.gather(mi.UInt32, min_thread_index_per_hash[0], hash0,
                      active=did_win)
            == expected_thread_idx
        ) & (
            dr.gather(mi.UInt32, min_thread_index_per_hash[1], hash1,
                      active=did_win)
            == expected_thread_idx
        )

        # Indicator: 1 if the path is valid and should be stored, 0 otherwise.
        output_indicator = mi.UInt32(1) & (is_non_specular | did_win)

        # Count new number of paths per source
        src_block_size = max_depth * samples_per_src * num_targets
        src_major_to_output_i, src_i = source_major_to_output_indices(
            samples_per_src, num_samples, num_targets, max_depth
        )
        output_indicator_src_major = dr.gather(
            mi.UInt32, output_indicator, src_major_to_output_i
        )
        new_paths_count_per_src = dr.block_prefix_sum(
            output_indicator_src_major,
            block_size=src_block_size,
            exclusive=True,
        )

        # Enforce the per-source path budget
        prev_paths_per_src = dr.gather(
            mi.UInt, paths_counter_per_source, src_i
        )
        output_indicator_src_major &= (
            prev_paths_per_src + new_paths_count_per_src < _u32(max_num_paths_per_src)  # opaque
        )

        # Fetch the updated indicator (in output index ordering)
        output_to_src_major_i = output_to_source_major_indices(
            samples_per_src, num_samples, num_targets, max_depth
        )
        output_indicator = dr.gather(
            mi.UInt32, output_indicator_src_major, output_to_src_major_i
        )

        output_offset: mi.UInt32 = dr.prefix_reduce(
            dr.ReduceOp.Add, output_indicator, exclusive=False
        )
        num_new_paths = _last(output_offset)  # opaque
        output_offset = paths.paths_counter + (output_offset - 1)
        is_valid_output = (output_offset < _u32(paths.buffer_size)) & (  # opaque
            output_indicator > 0
        )
        output_offset = dr.select(
            is_valid_output,
            output_offset,
            mi.UInt32(UINT32_MAX),
        )

        valid_output_src_major = dr.gather(
            mi.UInt32, mi.UInt32(1) & is_valid_output, src_major_to_output_i
        )
        new_paths_per_src = dr.block_sum(
            valid_output_src_major,
            block_size=src_block_size,
        )
        dr.scatter_add(
            paths_counter_per_source,
            new_paths_per_src,
            dr.arange(mi.UInt32, num_sources),
        )

        # Store `is_non_specular` (= valid) in the most significant bit of the
        # output offset array, so that we don't have to recompute it in Step 3.
        # This saves us a shadow ray trace.
        output_offset |= (mi.UInt32(1) & is_non_specular) << 31

        ########################################################################
        # Step 3: re-compute the paths and actually output them.
        ########################################################################
        thread_has_output = compute_thread_has_output(
            output_offset, num_samples, num_targets, max_depth
        )

        with dr.scoped_set_flag(dr.JitFlag.OptimizeLoops, False):
            # Re-seed so Step 3 replays the same sampling decisions as Step 1.
            self._sampler.seed(seed, num_samples)
            self._shoot_and_bounce_loop(
                *loop_args,
                self._sampler,
                output_offset=output_offset,
                thread_has_output=thread_has_output,
                src_boxes=src_boxes,
            )

        paths.advance_paths_counter(
            min(
                _u32(paths.buffer_size) - paths.paths_counter,  # opaque
                dr.opaque(mi.UInt32, num_new_paths),
            )
        )

    @dr.syntax
    def _shoot_and_bounce_loop(
        self,
        mi_scene: mi.Scene,
        src_positions: mi.Point3f,
        tgt_positions: mi.Point3f,
        samples_per_src: int,
        max_num_paths_per_src: int,
        max_depth: int,
        paths: PathsBuffer,
        paths_counter_per_source: mi.UInt,
        specular_reflection_enabled: bool,
        diffuse_reflection_enabled: bool,
        refraction_enabled: bool,
        diffraction_enabled: bool,
        edge_diffraction_enabled: bool,
        sampler: mi.Sampler,
        src_boxes: SourceExclusionBoxes | None = None,
        counting_mode: bool = False,
        output_offset: mi.UInt32 | None = None,
        thread_has_output: mi.Mask | None = None,
    ) -> Tuple[mi.UInt64, List[mi.UInt32]] | None:
        # pylint: disable=line-too-long
        """
        Executes shooting-and-bouncing of rays

        The paths buffer ``path`` is updated in-place.

        :param mi_scene: Mitsuba scene
        :param src_positions: Positions of the sources
        :param tgt_positions: Positions of the targets
        :param samples_per_src: Number of samples spawned per source
        :param max_num_paths_per_src: Maximum number of candidates per source
        :param max_depth:  Maximum path depths
        :param paths: Buffer storing the candidate paths. Updated in-place.
        :param paths_counter_per_source: Counts the number of paths found for each source
        :param specular_reflection_enabled: If set to `True`, then the specularly reflected paths are computed
        :param diffuse_reflection_enabled: If set to `True`, then the diffusely reflected paths are computed
        :param refraction_enabled: If set to `True`, then the refracted paths are computed
        :param diffraction_enabled: If set to `True`, then the diffracted paths are computed
        :param edge_diffraction_enabled: If set to `True`, then the diffraction on free floating edges is computed
        :param sampler: Sampler used to generate pseudo-random numbers
        :param src_boxes: Boxes which do not occlude the rays spawned from their source, one per source
        """
        assert counting_mode or (
            output_offset is not None
        ), "When not in counting mode, `output_offset` must be provided."

        num_sources = dr.shape(src_positions)[1]
        num_targets = dr.shape(tgt_positions)[1]
        num_samples = samples_per_src * num_sources

        # Rays
        ray = spawn_ray_from_sources(fibonacci_lattice, samples_per_src, src_positions)

        # Move the ray origins out of the boxes which do not occlude them.
        # Only the first segment of a path starts from a source, so this is
        # done before entering the loop. The directions of propagation are left
        # untouched, as the origins are moved along them.
        if dr.hint(src_boxes is not None, mode="scalar"):
            ray.o, _ = src_boxes.advance(
                ray.o, ray.d,
                source_index_per_sample(num_sources, samples_per_src))

        # Store direction of departure
        k_tx = dr.copy(ray.d)

        # Boolean indicating if the sample is a specular chain, i.e., if it
        # consists only of specular chains.
        specular_chain = dr.full(mi.Bool, True, num_samples)

        samples_data = None
        if dr.hint(counting_mode, mode="scalar"):
            # Hash of the paths.
            # It is computed only for specular chains, and used to not duplicate
            # specular chain candidates.
            # 64bit integer is used for hashing.
            # Multiple hash functions are used to mitigate the risk of different
            # paths having the same hash due to quantization.
            num_hashes = len(self.plane_hash_functions)
            hashes = [dr.zeros(mi.UInt64, num_samples) for _ in range(num_hashes)]

            # Counter indicating how many occurrences of a specular chain was found.
            # Specular chains are considered identical if they share the same
            # hash. Taking the hash modulo the size of the following array is used
            # to index this array and increment the counter. If the counter is > 0,
            # then the specular chain is not considered as new and not stored.
            # The size of the following array needs therefore to be large enough
            # to ensure that the number of collisions stays low and that candidates
            # are not discarded due to collisions.
            spec_counter_size = dr.maximum(
                max_num_paths_per_src, SBCandidateGenerator.MIN_SPEC_COUNT_SIZE
            )
            min_thread_index_per_hash = [
                dr.full(mi.UInt32, 0xFFFFFFFF, spec_counter_size * num_sources)
                for _ in range(num_hashes)
            ]

            # In counting mode, our only goal is to return a counter of the
            # number of paths to be stored for each path depth, each thread
            # and each target.
            # Layout: (path depth, thread index, target index)
            candidate_hashes = dr.full(
                mi.UInt64,
                NO_PATH_RECORDED_MARKER,
                max_depth * num_samples * num_targets,
            )
            src_indices = source_index_per_sample(num_sources, samples_per_src)

        else:
            # Structure storing the sample data, which is used to build the paths
            samples_data = SampleData(
                num_sources, samples_per_src, max_depth, diffraction_enabled
            )

            min_thread_index_per_hash = None
            hashes = None

        # Current depth
        depth = dr.full(mi.UInt, 1, num_samples)
        num_targets_o = _u32(num_targets)                    # opaque
        num_paths_per_depth_o = _u32(num_samples * num_targets)  # opaque

        # Mask indicating which rays are active
        active = dr.full(mi.Mask, True, num_samples)
        if dr.hint(thread_has_output is not None, mode="scalar"):
            assert output_offset is not None
            active &= thread_has_output
            active = dr.reorder_threads(mi.UInt32(active), num_bits=1, value=active)

        # Flag storing which types of interactions are locally enabled.
        # The booleans specular_reflection_enabled, diffuse_reflection_enabled,
        # etc. enable or disable interaction types globally.
        # Globally enabled interaction types can however be locally disabled,
        # i.e., disabled at the scale of a single path or intersection point.
        # For example, diffuse reflections are disabled for a path if diffraction
        # occurs. The following flag stores which interaction types are locally
        # enabled. It is initialized using the globally enabled interaction types.
        loc_en_inter = dr.full(mi.UInt, 0, num_samples)
        if dr.hint(specular_reflection_enabled, mode="scalar"):
            loc_en_inter |= InteractionType.SPECULAR
        if dr.hint(diffuse_reflection_enabled, mode="scalar"):
            loc_en_inter |= InteractionType.DIFFUSE
        if dr.hint(refraction_enabled, mode="scalar"):
            loc_en_inter |= InteractionType.REFRACTION
        if dr.hint(diffraction_enabled, mode="scalar"):
            loc_en_inter |= InteractionType.DIFFRACTION

        # Note: here and in the inner loop, we explicitly exclude some non-state
        # variables from the loop state so that DrJit doesn't have to trace
        # the loop body twice to figure it out.
        while dr.hint(
            active,
            label="shoot_and_bounce",
            exclude=[min_thread_index_per_hash, paths_counter_per_source],
        ):

            ########################################################
            # Test intersection with the scene and evaluate the
            # intersection
            ########################################################

            # Test intersection with the scene
            si_scene = mi_scene.ray_intersect(
                ray, coherent=True, ray_flags=mi.RayFlags.Minimal, active=active
            )

            # Deactivate rays that didn't hit the scene, i.e., that bounce-out
            # of the scene
            active &= si_scene.is_valid()

            # Samples the radio material
            sample1 = sampler.next_1d()
            sample2 = sampler.next_2d()
            sample2_diffraction = sampler.next_2d()
            s, n, wedges = self._sample_radio_material(
                si_scene,
                ray.o,
                ray.d,
                sample1,
                sample2,
                sample2_diffraction,
                loc_en_inter,
                diffraction_enabled,
                edge_diffraction_enabled,
                active,
            )
            # Direction of propagation of scattered wave in implicit world
            # frame
            k_world = s.wo
            # Interaction type
            int_type = dr.select(active, s.sampled_component, InteractionType.NONE)
            # Disable paths if a NONE interaction was sampled.
            # This happens if no interaction type is enabled
            active &= int_type != InteractionType.NONE
            # Flag indicating if the interaction is a specular reflection
            specular = int_type == InteractionType.SPECULAR
            # Flag indicating if the interaction is a transmission
            transmission = int_type == InteractionType.REFRACTION
            # Flag indicating if the interaction is a diffuse reflection
            diffuse = int_type == InteractionType.DIFFUSE
            # Flag indicating if the interaction is a diffraction
            diffraction = int_type == InteractionType.DIFFRACTION

            # Only first order diffraction is supported.
            # Therefore, we disable diffraction for future interactions
            # if diffraction is sampled.
            # Diffraction displaces the interaction point to an edge, which can
            # invalidate specular reflections, transmissions, and diffractions
            # that previously occurred. To avoid having to post-process path
            # segments in addition to the specular suffix (e.g., using the
            # image method), we disable paths that contain both diffuse and
            # diffraction.
            loc_en_inter[diffraction] &= ~(
                mi.UInt(InteractionType.DIFFUSE + InteractionType.DIFFRACTION)
            )
            loc_en_inter[diffuse] &= ~mi.UInt(InteractionType.DIFFRACTION)

            ########################################################
            # Update samples data
            ########################################################

            # Is the sample a specular chain?
            # A specular chain consists only of specular reflections,
            # or transmissions or diffractions
            specular_chain &= active & (specular | transmission | diffraction)
            if dr.hint(not counting_mode, mode="scalar"):
                samples_data.insert(
                    depth,
                    int_type,
                    si_scene.shape,
                    si_scene.prim_index,
                    wedges,
                    si_scene.p,
                    s.pdf,
                    active,
                )

            ########################################################
            # Paths counting or storage.
            # A path is stored if:
            # - It is a new specular chain
            # - It is valid, i.e., it connects to a target
            ########################################################

            if dr.hint(counting_mode, mode="scalar"):
                # Encode the current plane as a 3D vector
                for i in range(num_hashes):
                    plane_hash = self.plane_hash_functions[i](si_scene.n, si_scene.p)
                    edge_hash = self.edge_hash_functions[i](
                        wedges.o, wedges.o + wedges.e_hat * wedges.length
                    )
                    inter_hash = dr.select(
                        int_type == InteractionType.SPECULAR, plane_hash, int_type
                    )
                    inter_hash = dr.select(
                        int_type == InteractionType.DIFFRACTION, edge_hash, inter_hash
                    )
                    hashes[i] = hash_fnv1a(inter_hash, h=hashes[i])

            # Loop over all targets.
            # Target index
            t_idx = mi.UInt(0)
            while dr.hint(
                t_idx < num_targets_o,  # opaque
                label="shoot_and_bounce_inner",
                exclude=[min_thread_index_per_hash, paths_counter_per_source],
            ):
                # Linearized path index: (path depth, thread index, target index)
                current_path_i = (
                    (depth - 1) * num_paths_per_depth_o             # opaque
                    + dr.arange(mi.UInt32, num_samples) * num_targets_o  # opaque
                    + t_idx
                )

                # Position of the target with index t_idx
                tgt_position = dr.gather(mi.Point3f, tgt_positions, t_idx)
                los_ray = si_scene.spawn_ray_to(tgt_position)

                if dr.hint(counting_mode, mode="scalar"):
                    # Test line-of-sight with the target from the current
                    # interaction point
                    los_blocked = mi_scene.ray_test(los_ray, active=active)
                    los_visible = ~los_blocked

                    # If the interaction is valid and if the target is visible from
                    # the intersection point, then the path is marked as valid.

                    # It is also required that the target is on the same side of
                    # the intersected surface than the incident wave.
                    # `n`` is the normal to the intersected surface oriented towards
                    # the incident half-space
                    # `los_ray.d` is from the intersection point to the target
                    target_incident_side = dr.dot(n, los_ray.d) > 0.0
                    valid = los_visible & diffuse & target_incident_side

                    # If this path is a specular chain, then we hash it to ensure
                    # that it is a new paths.
                    # A specular chain is only considered as candidate if the
                    # intersection point is in LoS with the target. This condition
                    # is used as an heuristic to reduce the number of candidates.
                    # It also helps to reduce the number of access to the hash table
                    # storing the specular chain counter, and therefore reduces the
                    # number of collisions.
                    new_specular = specular_chain & los_visible

                    # A specular chain is considered as new, and therefore should
                    # be stored in the `path` structure, if its hash has not been
                    # already observed. To ensure that the path has not
                    # already been stored for the target `t_idx`, we combine it with
                    # the path hash.
                    # We use several hash functions to mitigate the risk of slightly
                    # different paths having a different hash due to numerical precision issues.
                    # A path is considered as new if all hashes are new.
                    assert num_hashes == 2
                    assert (
                        spec_counter_size < 0xFFFFFFFF
                    ), "Hash table too large to combine two indices into a single 64-bit integer"

                    thread_idx = dr.arange(mi.UInt32, dr.width(active))
                    hashes_to_combine = []
                    for i in range(num_hashes):
                        counter_ind = hash_for_target(
                            t_idx,
                            hashes[i],
                            spec_counter_size,
                            src_indices,
                        )
                        hashes_to_combine.append(counter_ind)

                        # Note on hash collision detection/resolution:
                        # - Thread A: h0 = 10, h1 = 20
                        # - Thread B: h0 = 40, h1 = 20
                        # If Thread B wins the h0 race:
                        # - flags[0][40] <= B
                        # - Thread B goes on to min-reduce B into flags[1][20]
                        # - If Thread A wins its own h0 race:
                        #   - flags[0][10] <= A
                        #   - Thread A goes on to min-reduce A into flags[1][20]
                        #   - Final state: flags[0][10] <= A, flags[1][20] <= A
                        # - Otherwise (Thread A lost its h0 race):
                        #   - flags[0][10] < A
                        #   - Thread A does not write anything further.
                        #   - Final state: flags[0][10] < A, flags[1][20] <= B
                        #
                        # So if we enforce that the first race is won before
                        # writing into the second `flags[1]` array, then we
                        # re-introduce some non-determinism.
                        # If we don't enforce it, then we may lose some paths
                        # due to cross-collisions (?).
                        #
                        # Note: since we are not enforcing winning the
                        # first race before writing into the second `min_thread_index_per_hash[1]` array,
                        # then we don't really need to actually track the result
                        # of the races right now. Step 2 will take care of it.
                        dr.scatter_reduce(
                            dr.ReduceOp.Min,
                            target=min_thread_index_per_hash[i],
                            index=counter_ind,
                            value=thread_idx,
                            active=(active & new_specular),
                        )

                    # Store the combined hash indices so that we can double-check later whether we won this race.
                    # We use a special value to indicate threads that want
                    # to store a non-specular path, and are therefore not
                    # subject to the hash collision resolution.
                    to_store = dr.select(
                        new_specular,
                        combine_hashes_to_u64(
                            hashes_to_combine[0], hashes_to_combine[1]
                        ),
                        NON_SPECULAR_PATH_MARKER,
                    )
                    del thread_idx, hashes_to_combine

                    # Record the hash table indices for this path so that we can
                    # check in Step 2 whether this thread actually won the race.
                    store = active & (valid | new_specular)
                    dr.scatter(
                        candidate_hashes, to_store, current_path_i, active=store
                    )

                else:
                    # Read which offset we are supposed to store the path to.
                    output_offset_i = dr.gather(
                        mi.UInt32, output_offset, current_path_i, active=active
                    )
                    # Extract the `valid` vs `new_specular` flag for this path.
                    # This allows us to skip tracing a shadow ray, etc just
                    # to figure out this flag.
                    valid = (output_offset_i >> 31) > 0
                    output_offset_i &= 0x7FFFFFFF

                    # Note: all output space constraints and max paths per
                    # source were already enforced when assigning the output
                    # offset, so we can directly use it here. Likewise, no
                    # need to check that the path is valid or a new specular
                    # chain, this has all been resolved in Steps 1-2.
                    store = active & (output_offset_i < _u32(paths.buffer_size))  # opaque
                    paths.add_paths(
                        depth,
                        output_offset_i,
                        samples_data,
                        valid,
                        t_idx,
                        k_tx,
                        -los_ray.d,
                        store,
                    )

                t_idx += 1

            ####################################
            # Prepare next iteration
            ####################################

            # Deactivate rays if the maximum depth is reached
            depth += 1
            active &= depth <= max_depth

            # Spawn rays for next iteration
            ray = si_scene.spawn_ray(d=k_world)

            # Reset the value of specular_chain in case of a diffuse reflection
            specular_chain |= diffuse

        if dr.hint(counting_mode, mode="scalar"):
            return candidate_hashes, min_thread_index_per_hash


def hash_for_target(
    t_idx: mi.UInt,
    running_path_hash: mi.UInt64,
    counter_size: int,
    source_indices: mi.UInt,
):
    path_target_hash = hash_fnv1a(t_idx, h=running_path_hash)
    counter_ind = \
        (path_target_hash % counter_size) + counter_size * source_indices
    return counter_ind


def combine_hashes_to_u64(hash1: mi.UInt64, hash2: mi.UInt64) -> mi.UInt64:
    return ((mi.UInt64(hash1) & mi.UInt64(0xFFFFFFFF)) << 32) | (
        mi.UInt64(hash2) & mi.UInt64(0xFFFFFFFF)
    )


def extract_hashes_from_u64(combined: mi.UInt64) -> tuple[mi.UInt32, mi.UInt32]:
    return (
        mi.UInt32((combined >> 32) & mi.UInt64(0xFFFFFFFF)),
        mi.UInt32(combined & mi.UInt64(0xFFFFFFFF)),
    )


def source_major_to_output_indices(
    samples_per_src: int,
    num_samples: int,
    num_targets: int,
    max_depth: int,
) -> Tuple[mi.UInt32, mi.UInt32]:
    """Map source-major candidate lanes to the loop's output layout."""

    num_candidates = max_depth * num_samples * num_targets
    src_block_size = max_depth * samples_per_src * num_targets

    source_major_i = dr.arange(mi.UInt32, num_candidates)
    src_i = source_major_i // _u32(src_block_size)
    within_src_i = source_major_i % _u32(src_block_size)
    depth_i = within_src_i // _u32(samples_per_src * num_targets)
    within_depth_i = within_src_i % _u32(samples_per_src * num_targets)
    sample_i = within_depth_i // _u32(num_targets)
    target_i = within_depth_i % _u32(num_targets)

    output_i = (
        depth_i * _u32(num_samples * num_targets)
        + (src_i * _u32(samples_per_src) + sample_i)
        * _u32(num_targets)
        + target_i
    )

    return output_i, src_i


def output_to_source_major_indices(
    samples_per_src: int,
    num_samples: int,
    num_targets: int,
    max_depth: int,
) -> mi.UInt32:
    """Map the loop's output-layout lanes to source-major candidate lanes."""

    num_candidates = max_depth * num_samples * num_targets
    src_block_size = max_depth * samples_per_src * num_targets

    output_i = dr.arange(mi.UInt32, num_candidates)
    depth_i = output_i // _u32(num_samples * num_targets)
    within_depth_i = output_i % _u32(num_samples * num_targets)
    sample_i = within_depth_i // _u32(num_targets)
    target_i = within_depth_i % _u32(num_targets)
    src_i = sample_i // _u32(samples_per_src)
    sample_in_src_i = sample_i % _u32(samples_per_src)

    return (
        src_i * _u32(src_block_size)
        + depth_i * _u32(samples_per_src * num_targets)
        + sample_in_src_i * _u32(num_targets)
        + target_i
    )


def compute_thread_has_output(
    output_offset: mi.UInt32, num_samples: int, num_targets: int, max_depth: int
) -> mi.Mask:
    # Flat buffer order is (depth, thread, target) with target fastest;
    # reorder so each thread owns a contiguous block of max_depth * num_targets
    # lanes (depth, then target). Gather with these indices reads thread-major.
    per_thread_block = max_depth * num_targets
    reorder = dr.arange(mi.UInt32, num_samples * per_thread_block)
    thread = reorder // _u32(per_thread_block)
    within = reorder % _u32(per_thread_block)
    depth = within // _u32(num_targets)
    tgt = within % _u32(num_targets)
    all_output_indices_per_thread = (
        depth * _u32(num_samples * num_targets)
        + thread * _u32(num_targets)
        + tgt
    )
    is_valid_output = (
        dr.gather(mi.UInt32, output_offset, all_output_indices_per_thread)
        < UINT32_MAX
    )
    thread_has_output = (
        dr.block_sum(
            mi.UInt32(is_valid_output),
            block_size=(max_depth * num_targets),
        )
        > 0
    )
    assert dr.width(thread_has_output) == num_samples
    return thread_has_output
