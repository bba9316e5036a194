"""Do the tests fail when the code is wrong? Plant bugs one at a time and run the suite.

Each mutation replaces one exact snippet of pinlin's source, in a temporary copy of the
checkout's last commit, with a plausible bug (a consistently rescaled parameter, a flipped
sign, a dropped term or check). The suite then runs against that copy (pytest -x -q,
stopping at the first failure): a mutation is *caught* when some test fails and *survives*
when all pass. A snippet that no longer exists in the source is reported as *stale* (the
code moved: update the list). Not run by CI: it costs one suite run per survivor (~3 min)
and a few seconds per caught one.

Usage: python validation/mutation.py [--jobs K] [NAME ...]    (default: all, one at a time;
--jobs 2 runs two mutations at once, each in its own copy: half the time on two cores)
Writes validation/reports/mutation.md.
"""

from __future__ import annotations

import argparse
import os
import queue
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from pinlin.files import write_text_atomic  # noqa: E402

REPORT = ROOT / "validation" / "reports" / "mutation.md"
#: A suite run against one mutation that takes longer than this [s] is stopped and reported
#: as "hung" (not caught: no test failed); an unmutated run takes 3-6 minutes here.
RUN_TIMEOUT = 1200.0

#: name: (file, snippet, replacement, what the bug is)
MUTATIONS: dict[str, tuple[str, str, str, str]] = {
    "alpha_doubled": (
        "pinlin/formulations/constrained.py", "    return p.alpha, p.mu, p.omega",
        "    return 2 * p.alpha, p.mu, p.omega",
        "penalty factor alpha doubled everywhere (model and info alike)"),
    "mu_halved": (
        "pinlin/formulations/constrained.py", "    return p.alpha, p.mu, p.omega",
        "    return p.alpha, 0.5 * p.mu, p.omega",
        "penalty damping ratio mu halved everywhere"),
    "mechanism_outputs_independent_only": (
        "pinlin/formulations/constrained.py",
        "Cout = np.hstack([Cout[:, :nv] @ R, Cout[:, nv:] @ R])",
        "Cout = np.hstack([Cout[:, cp.partition.independent], "
        "Cout[:, nv:][:, cp.partition.independent]])",
        "a mechanism's output C ignores the dependent coordinates' motion"),
    "canonical_output_mp": (
        "pinlin/formulations/canonical.py",
        "Cout = np.hstack([Cfull[:, n:] @ Mp_inv, Cfull[:, :n]])",
        "Cout = np.hstack([Cfull[:, n:] @ Mp, Cfull[:, :n]])",
        "canonical output C reads v = M_p p instead of M_p^-1 p"),
    "penalty_b_sign": (
        "pinlin/formulations/constrained.py", "    B[n:] = Q @ XB",
        "    B[n:] = -(Q @ XB)", "penalty model's B with its sign flipped"),
    "canonical_b_sign": (
        "pinlin/formulations/canonical.py", "    B = np.vstack([Bu, np.zeros_like(Bu)])",
        "    B = np.vstack([-Bu, np.zeros_like(Bu)])", "canonical model's B with its sign flipped"),
    "mjcf_drops_armature": (
        "pinlin/mjcf.py", "        joint.armature = float(system.model.armature[j.idx_v])",
        "        joint.armature = 0.0", "MuJoCo export drops the armature"),
    "files_drop_g": (
        "pinlin/model_files.py", "    names = {k: list(v) for k, v in names.items()}",
        "    arrays = {k: v for k, v in arrays.items() if k != 'G'}\n"
        "    names = {k: list(v) for k, v in names.items()}",
        "saved model files silently drop the constraint Jacobian G"),
    "weld_hessian_without_rotation_terms": (
        "pinlin/constraint_derivatives.py",
        "                out[j] -= lr @ (0.5 * np.cross(d[:, j], d.T).T "
        "+ np.cross(d[:, j], w2.T).T)\n", "",
        "a weld's geometric stiffness without its -1/2 d x d - d x w2 rotation terms"),
    "point_hessian_wrong_ancestor": (
        "pinlin/constraint_derivatives.py", "    return X * upper + (X * strict).T",
        "    return X.T * upper + (X.T * strict).T",
        "the batched point-loop stiffness takes the descendant's axis for the pair's ancestor"),
    "moving_base_without_kinematic_block": (
        "pinlin/formulations/moving_manifold.py",
        "    if N is not None:\n        A[:nz, :nz] = (N @ R)[z]\n", "",
        "a standing robot at a moving state without the base's -1/2 ad(v0) R upper block"),
    "moving_weld_acceleration_al2_sign": (
        "pinlin/constraint_derivatives.py",
        "LWA).angular - al2\n                                    - _cross(d, w2))",
        "LWA).angular + al2\n                                    - _cross(d, w2))",
        "a weld loop's rotation-row acceleration adds the second frame's angular acceleration"),
    "moving_manifold_w_sign": (
        "pinlin/formulations/moving_manifold.py",
        "        W[dep] = -np.linalg.solve(G[:, dep], dvel[rows])",
        "        W[dep] = np.linalg.solve(G[:, dep], dvel[rows])",
        "the velocity's variation W along a standing robot's motion with its sign flipped"),
    "moving_weld_velocity_frame1_only": (
        "pinlin/constraint_derivatives.py",
        "            vel[row + 3:row + 6] = d\n",
        "            vel[row + 3:row + 6] = v1.angular\n",
        "a weld loop's rotation-row velocity without the second frame's"),
    "moving_penalty_base_symmetric": (
        "pinlin/formulations/motion.py",
        "    if moving_manifold.applies(system):  # a floating base on point contacts: Phi_qq not",
        "    if False:  # a floating base on point contacts: Phi_qq not",
        "a floating base's penalty model at a moving state with a symmetric Phi_qq"),
    "hessian_base_symmetrized": (
        "pinlin/constraint_derivatives.py", "        sym[block, block] = out.T[block, block]",
        "        pass",
        "a floating base's constraint stiffness symmetrized (its exact part is not symmetric)"),
    "estimate_without_rounding": (
        "pinlin/derivatives.py",
        "    rounding = NOISE_SIGMAS * noise / scale + FORMULATION_ROUNDING",
        "    rounding = 0.0",
        "finite-difference error estimate without its measured-noise part"),
    "no_step_range": (
        "pinlin/derivatives.py", "        if not STEP_MIN <= h <= STEP_MAX:",
        "        if False:", "finite-difference steps of 2 pi or 1e-300 accepted"),
    "no_canonical_check": (
        "pinlin/formulations/canonical.py",
        "    gap = (_check_canonical_spectrum(A, A_pen, G, alpha, system.scene.name) if G.size",
        "    gap = (0.0 if G.size",
        "canonical model returned at any alpha, its spectrum unchecked"),
    "no_sensitivity_check": (
        "pinlin/formulations/constrained.py",
        "    if cp.partition.condition > SENSITIVITY_CHECK:", "    if False:",
        "no warning near a singular position of a mechanism"),
    "no_finiteness_check": (
        "pinlin/linear_model.py", "        check_finite(fields, model)", "        pass",
        "models with NaN or inf returned by the fast constructor"),
    "urdfdom_complaints_ignored": (
        "pinlin/urdf_io.py", "    if complaints:\n        raise UrdfError",
        "    if False:\n        raise UrdfError",
        "urdfdom's complaints on stderr ignored (the backstop behind the XML checks)"),
    "mjcf_contacts_dropped": (
        "pinlin/mjcf.py", "    _add_contacts(spec, system, bodies, solref, solimp)\n", "",
        "MuJoCo export forgets the scene's contacts (a standing robot falls freely)"),
    "contact_site_at_link_origin": (
        "pinlin/mjcf.py", "            return f.name, rel.translation.copy(), _wxyz(rel.rotation)",
        "            return f.name, np.zeros(3), _wxyz(rel.rotation)",
        "a contact or loop at a joint's frame exported at its link's origin"),
    "response_nonfinite_returned": (
        "pinlin/response.py", "    _check_finite(model, t, x, y)\n    return _result",
        "    return _result", "a response beyond float64's range returned with inf/NaN"),
    "outputs_replace_any_file": (
        "pinlin/files.py", "    check_replaceable(path, target, kind)\n", "",
        "an output replaces whatever file (or link target) has its name"),
    "figure_anchors_at_origin": (
        "pinlin/stick_figure.py", "self._anchors[ident] if kind == \"anchor\" else",
        "pin.SE3.Identity() if kind == \"anchor\" else",
        "mode pictures draw every contact anchor at the world origin"),
    "schedule_statics_without_springs": (
        "pinlin/rest_schedule.py",
        "    _, held, scale = _held_force(system, Q)\n    S = system.input_matrix",
        "    held, _, scale = _held_force(system, Q)\n    S = system.input_matrix",
        "a mechanism's gain schedule solves its holding inputs without the springs"),
    "schedule_never_refuses": (
        "pinlin/rest_schedule.py",
        "    equilibrium = free[np.arange(N), worst] <= _tolerances(scale)",
        "    equilibrium = np.ones(N, dtype=bool)",
        "a gain schedule of an open chain calls every point an equilibrium"),
    "moving_fd_without_phi_qq_a": (
        "pinlin/formulations/moving_fd.py",
        "        return cons.jacobian(q)[rows] @ op.a + cons.bias_acceleration(q, op.v)[rows]",
        "        return cons.bias_acceleration(q, op.v)[rows]",
        "a mechanism's numerical model at a moving state drops Phi_qq[a0] from c_q"),
    "mass_check_skipped": (
        "pinlin/formulations/independent.py", "    elif check_mass is not None:",
        "    elif False:",
        "an open chain's M^-1 is never checked when its check waits for the RNEA derivatives"),
    "given_state_never_equilibrium": (
        "pinlin/formulations/motion.py",
        "    equilibrium = not np.any(v) and float(np.abs(residual).max(initial=0.0)) <= tol",
        "    equilibrium = False",
        "a constrained system given at rest with its holding inputs is never an equilibrium"),
    "trajectory_discretize_overflow_kept": (
        "pinlin/trajectory_model.py",
        "        refuse_overflow(self.name, dt, method, A_d, B_d, f_d)\n",
        "", "a trajectory discretized over too long a dt keeps its NaN matrices"),
    "penalty_limit_dropped": (
        "pinlin/options.py", "            if not value <= PENALTY_LIMIT:",
        "            if False:", "penalty options whose products overflow are accepted"),
    "frequency_pole_left_nan": (
        "pinlin/frequency.py", "    H[pole] = np.inf\n", "",
        "a frequency response exactly at a pole keeps the 0 placeholder instead of inf"),
    "one_joint_jacobian_flat": (
        "pinlin/loop_kernels.py",
        "    return pin.getFrameJacobian(model, data, frame, LWA).reshape(6, -1)\n",
        "    return pin.getFrameJacobian(model, data, frame, LWA)\n",
        "a one-joint robot's 6x1 frame Jacobian used as eigenpy returns it (a vector)"),
    "symmetric_mass_unchecked": (
        "pinlin/modal.py", "    for mat in (model.K, model.M):", "    for mat in (model.K,):",
        "modal takes the symmetric pencil path with a non-symmetric M"),
    "rigid_threshold_from_constraint_modes": (
        "pinlin/modal.py", "        largest = float(magnitudes[physical].max())\n", "",
        "modal's rigid threshold follows a penalty model's constraint modes again"),
    "fd_estimate_relative_to_all_of_A": (
        "pinlin/formulations/constrained.py",
        "        out.update(error_estimate(A, A_alt, rounding, scale))",
        "        out.update(error_estimate(A, A_alt, rounding))",
        "a penalty model's finite-difference error estimate divided by max |A|"),
    "standing_chart_jacobian_dropped": (
        "pinlin/simulation_ode.py",
        "        cdot = chart_rate(self.model, self.q_ref, q, v, self.lie)\n",
        "        cdot = v\n",
        "a standing robot's simulation integrates the base's tangent velocity as if its chart "
        "were additive"),
    "write_not_atomic": (
        "pinlin/files.py", "        yield tmp\n", "        yield target\n",
        "files written in place instead of through a temporary file"),
    'assembly_curvature_sign': (
        'pinlin/trajectory_assembly.py',
        'step[dep] += x[:, 0] + curvature(back[z], past[z]) * (past[dep] + x[:, 1])',
        'step[dep] += x[:, 0] - curvature(back[z], past[z]) * (past[dep] + x[:, 1])',
        "a mechanism trajectory's assembly predictor subtracts the curvature term"),
    'assembly_closed_tolerance_loose': (
        'pinlin/trajectory_assembly.py',
        'return (np.abs(phi) / self.cons.row_scale).max(axis=1, initial=0.0) <= ASSEMBLY_TOL',
        'return (np.abs(phi) / self.cons.row_scale).max(axis=1, initial=0.0) <= 100 * ASSEMBLY_TO'
        'L',
        'trajectory points whose loops are open by up to 100 ASSEMBLY_TOL are kept as given'),
    'mat_compressed_first_array_only': (
        'pinlin/mat_check.py',
        'if len(inner) != 1 or inner[0][0] != MI_MATRIX:',
        'if not inner or inner[0][0] != MI_MATRIX:',
        'a compressed .mat element is checked only up to its first array (the rest reaches scipy)'),
    'mat_numeric_short_data_accepted': (
        'pinlin/mat_check.py',
        'any(t not in NUMERIC_TYPES or len(data) != count',
        'any(t not in NUMERIC_TYPES or len(data) > count',
        'a numeric .mat array with fewer entries than its dimensions say passes the check'),
    'euler_position_block_without_avv': (
        'pinlin/discretization.py',
        'A_d[:nv, nv:] = dt * (Aqv @ (eye + dt * Avv))',
        'A_d[:nv, nv:] = dt * Aqv',
        "the semi-implicit Euler step's dq+/dv block forgets that v+ includes dt A_vv v"),
    'stacked_euler_drift_without_dt2': (
        'pinlin/discretization.py',
        'f_d = np.concatenate([dt * f0[:, :nv] + dt * dt * (Aqv @ f0[:, nv:, None])[..., 0],',
        'f_d = np.concatenate([dt * f0[:, :nv],',
        "a trajectory's Euler drift misses the dt^2 A_qv f0_v position term"),
    'stacked_zoh_block_off_by_one': (
        'pinlin/discretization.py',
        'hi = min(N, lo + ZOH_BLOCK)',
        'hi = min(N, lo + ZOH_BLOCK - 1)',
        'the blocked stacked ZOH skips the last point of each 128-point block'),
    'zoh_survives_slowest_mode': (
        'pinlin/discretization.py',
        'growth = float(np.linalg.eigvals(A).real.max()) * dt',
        'growth = float(np.linalg.eigvals(A).real.min()) * dt',
        'the ZOH accuracy check is skipped when any (not every) mode decays within dt'),
    'discrete_impulse_times_dt': (
        'pinlin/response.py',
        'U[0] += impulse / dt',
        'U[0] += impulse * dt',
        "a discrete model's impulse becomes a * dt instead of a / dt"),
    'jordan_block_input_next_sample': (
        'pinlin/response.py',
        'forced = (np.einsum("kij,kj->ki", Gu[which], U[:-1])',
        'forced = (np.einsum("kij,kj->ki", Gu[which], U[1:])',
        'modal response: Jordan/Schur blocks hold the next sample instead of the current one'),
    'exact_warning_on_shortest_step': (
        'pinlin/response.py',
        '        longest = float(np.diff(t).max()) if len(t) > 1 else 0.0',
        '        longest = float(np.diff(t).min()) if len(t) > 1 else 0.0',
        'exact response checks the rounding of its shortest step, not its longest'),
    'stiff_criterion_or': (
        'pinlin/simulation.py',
        'if stiff > STIFF_LIMIT and rho > STIFF_RATIO * resolve:',
        'if stiff > STIFF_LIMIT or rho > STIFF_RATIO * resolve:',
        'simulate calls a problem stiff when either criterion holds'),
    'held_sample_searchsorted_left': (
        'pinlin/simulation_inputs.py',
        'k = max(int(np.searchsorted(self.t, t, side="right")) - 1, 0)',
        'k = max(int(np.searchsorted(self.t, t, side="left")) - 1, 0)',
        'simulate holds the previous sample at each sample time'),
    'horizon_decay_ignored': (
        'pinlin/simulation.py',
        'np.minimum(T, PERSIST / np.where(decay > 0, decay, 1.0))',
        'T',
        "simulate counts a decaying mode's periods over the whole horizon"),
    'mechanism_initial_velocity_drops_v0': (
        'pinlin/simulation_ode.py',
        's = np.concatenate([dz, self.op.v[self.z] + dzdot])',
        's = np.concatenate([dz, dzdot])',
        "a mechanism's simulation starts from dz' alone, forgetting v0"),
    'validity_atol_check_without_amplitude': (
        'pinlin/validity.py',
        'if NOISE_ATOL * atol * scale / smallest >= tolerance:',
        'if NOISE_ATOL * atol * scale >= tolerance:',
        "validity's atol noise check ignores the smallest amplitude"),
    'direction_horizon_longest_unstable': (
        'pinlin/validity.py',
        'return min(unstable), period, "the shortest unstable mode horizon"',
        'return max(unstable), period, "the shortest unstable mode horizon"',
        "a direction's horizon takes the longest unstable horizon"),
    'eigenvalue_condition_ignored': (
        'pinlin/modal_coordinates.py',
        'spread = kappa * worst',
        'spread = kappa',
        'diagonal modal form accepted on kappa(R) alone, eigenvalue conditions ignored'),
    'closed_form_residual_unchecked': (
        'pinlin/modal_coordinates.py',
        'if left is None or result.residual <= RESIDUAL_LIMIT:',
        'if True:',
        'closed-form symmetric vectors kept whatever residual they leave'),
    'block_gain_cluster_radius': (
        'pinlin/frequency.py',
        'radius = np.finfo(float).eps ** (1.0 / k) * k * max(1.0, float(np.abs(M).max()))',
        'radius = np.finfo(float).eps * k * max(1.0, float(np.abs(M).max()))',
        "a singular block's eigenvalue cluster radius without the eps^(1/k) of defective blocks"),
    'cheap_bound_margin_inverted': (
        'pinlin/eigensolvers.py',
        'if worst_column * _EPS * frobenius <= EIGENVALUE_RISK / RISK_MARGIN:',
        'if worst_column * _EPS * frobenius <= EIGENVALUE_RISK * RISK_MARGIN:',
        "modal's cheap risk bound clears models up to 4x beyond the warning threshold"),
    'sensitivity_moving_index': (
        'pinlin/rest_schedule.py',
        'candidates.append(int(moving[np.argmax(condition[moving])]))',
        'candidates.append(int(np.argmax(condition[moving])))',
        'the moving point checked for sensitivity indexed in the moving subset, not the trajector'
        'y'),
    'at_rest_mechanism_moving': (
        'pinlin/trajectory_model.py',
        'if model.lam is not None and not model.info.get("at_rest"):',
        'if model.lam is not None:',
        "a mechanism's schedule point at rest comes back as a moving (non-equilibrium) model"),
    'point_sizes_a_unchecked': (
        'pinlin/model_checks.py',
        'for key in ("a", "residual"):',
        'for key in ("residual",):',
        "an operating point's a of the wrong size is accepted"),
    'graph_dissipative_output_factor_swapped': (
        'pinlin/graph/matrix.py',
        'factor = 1.0 / branch.value if in_tree else branch.value',
        'factor = branch.value if in_tree else 1.0 / branch.value',
        "a resistor's secondary output uses R where 1/R belongs and back"),
    'moving_batch_cv_without_factor_two': (
        'pinlin/formulations/moving_batch.py',
        'rhs[:, nv:, nv:2 * nv] = -2.0 * Jv',
        'rhs[:, nv:, nv:2 * nv] = -Jv',
        'c_v = Phi_qq[v, .] instead of 2 Phi_qq[v, .] in the moving mechanism model'),
    'moving_batch_output_without_W': (
        'pinlin/formulations/moving_batch.py',
        'return np.concatenate([Cq @ R + Cv @ W, Cv @ R], axis=2)',
        'return np.concatenate([Cq @ R, Cv @ R], axis=2)',
        "a moving mechanism trajectory's velocity outputs miss the W dz term"),
    'loop_kernel_dgamma_drops_E_term': (
        'pinlin/loop_kernels.py',
        'dgamma = _cross(dO, lin) + _cross(Om, D) + _cross(E, V) + _cross(ang, dV)',
        'dgamma = _cross(dO, lin) + _cross(Om, D) + _cross(ang, dV)',
        'd gamma / dq without the E_k x V_k term (axis turning along v)'),
    'least_norm_family_always': (
        'pinlin/rest_schedule.py',
        'family = [int(k) for k in np.flatnonzero(keep.sum(axis=1) < columns)]',
        'family = [int(k) for k in np.flatnonzero(keep.sum(axis=1) <= columns)]',
        'every schedule point of a mechanism reported as a least-norm (non-unique) split'),
    'feedback_sign': (
        'pinlin/simulation_inputs.py',
        '            self.feedback = lambda t, x: -(gain @ x)',
        '            self.feedback = lambda t, x: gain @ x',
        'a gain over all coordinates applied as du = +K x'),
    'feedback_open_loop_stiffness': (
        'pinlin/simulation.py',
        '        return dyn.rhs(t0, s, inputs.total(t0, lambda: dyn.model_state(s), u))',
        '        return dyn.rhs(t0, s, u)',
        'the stiffness criterion judges the open loop, not the closed one'),
    'feedback_wrong_columns': (
        'pinlin/simulation_inputs.py',
        '            self.feedback = lambda t, x: -(gain @ x[picked])',
        '            self.feedback = lambda t, x: -(gain @ x[:2 * nz])',
        "a mechanism's gain reads the first 2 nz states instead of [dz; dz']"),
    'closed_loop_output_unchanged': (
        'pinlin/closed_loop.py',
        'model.C - model.D @ gain, model.D,',
        'model.C, model.D,',
        "the closed loop's outputs leave out the feedthrough of the feedback (C, not C - D K)"),
    'closed_loop_damping_from_positions': (
        'pinlin/closed_loop.py',
        '"C_damp": model.C_damp + model.Bu @ Kv,',
        '"C_damp": model.C_damp + model.Bu @ Kq,',
        "the closed loop's damping takes the position gains"),
    'exact_check_skipped_after_step_warning': (
        'pinlin/response.py',
        '        if longest:\n            _check_rounding(',
        '        if longest and not said:\n            _check_rounding(',
        "the exact response's rounding check is skipped where the long-step warning fired"),
    'exact_check_one_sample_unscaled': (
        'pinlin/response.py', 'ROUNDING_SAMPLES = 2\nROUNDING_FACTOR = 10.0',
        'ROUNDING_SAMPLES = 1\nROUNDING_FACTOR = 1.0',
        "the exact response's error estimate: one perturbed march, no safety factor"),
    'gain_columns_in_file_order': (
        'pinlin/gain_files.py', 'K[row, column[k]] = csv_number(',
        'K[row, k] = csv_number(',
        "a gain file's columns taken in the file's order, not put in the model's"),
    'gain_design_point_unchecked': (
        'pinlin/gain_files.py', '        if not same_point(there, here):',
        '        if False:',
        "a gain file's design point is read but not compared with the model's"),
    'history_replaces_a_gain': (
        'pinlin/files.py',
        '                return kind in (None, "gain")',
        '                return True',
        "a time history may replace a gain file"),
    'batch_screen_ignores_condition': (
        'pinlin/batch_screen.py',
        '    return ~((estimate > 0.0) & (estimate < SCREEN_MARGIN * limit)',
        '    return ~((estimate > 0.0) & (estimate < 1e300)',
        "the batch's mass screen flags only a non-positive diagonal of M^-1, not a condition "
        "that reaches the refusal limit"),
    'batch_screen_never_warns': (
        'pinlin/batch_screen.py',
        '    return traces > SCREEN_MARGIN * threshold',
        '    return traces > 1e300',
        "the batch never flags a point for the single call's ill-conditioning warning"),
    'history_without_marker': (
        'pinlin/cli_histories.py',
        '        lines = [marker, ",".join(["t", *names])]',
        '        lines = [",".join(["t", *names])]',
        "a CSV time history is written without its marker line (it cannot be told from a "
        "user's states file)"),
    'statics_split_unweighted': (
        'pinlin/equilibrium.py', '    return (np.where(force, length, 1.0),',
        '    return (np.ones(np.broadcast(force, length).shape),',
        "a standing robot's least-norm [u0; lam] adds N to N*m (the split depends on the "
        "robot's size)"),
    'schedule_split_unweighted': (
        'pinlin/rest_schedule.py', '    if mixed.size:', '    if False:',
        "a schedule's stacked statics take the plain least-norm split where a single call "
        "takes the one in N*m"),
    'sliding_mode_titled_in_rad': (
        'pinlin/mode_pictures.py', '    return name, "m" if linear else "rad"',
        '    return name, "rad"',
        "a mode picture gives a slider's amplitude in rad"),
    'penalty_error_halved': (
        'pinlin/formulations/penalty_error.py',
        '    shift = 2.0 * np.einsum("ij,ij->j", y.conj(), (A - A_double) @ x)',
        '    shift = np.einsum("ij,ij->j", y.conj(), (A - A_double) @ x)',
        "the penalty's error taken as lam(alpha) - lam(2 alpha), half of it"),
    'penalty_error_counts_constraint_modes': (
        'pinlin/formulations/penalty_error.py',
        '    physical = ~constraint_columns(G, right[:n]) & (np.abs(lam) > scale)',
        '    physical = np.abs(lam) > scale',
        "the penalty's error estimate counts the constraint modes (a defective double root "
        "with mu = 1): warnings on every mechanism"),
    'moving_penalty_error_same_alpha': (
        'pinlin/formulations/motion.py',
        '    error = penalty_error(A, linearized(2.0 * alpha)[0], G, alpha, system.scene.name)',
        '    error = penalty_error(A, linearized(alpha)[0], G, alpha, system.scene.name)',
        "a moving state's penalty error estimated as zero (no warning at a far too small alpha)"),
    'simulate_atol_unscaled': (
        'pinlin/simulation.py',
        '                             lambda d: np.where(d.linear_state(), atol * length, atol))',
        '                             lambda d: np.full(d.linear_state().size, atol))',
        "simulate's default absolute tolerance 1e-12 m on a slider of any size (a 61 um "
        "mechanism integrated 1e4 times looser than its angles loses its loops)"),
    'sensitivity_move_mixed_units': (
        'pinlin/formulations/constrained.py',
        '    length = np.ones(dep.size) if factors is None else factors[1][dep]',
        '    length = np.ones(dep.size)',
        "the sensitivity check's move near a singular position is Phi_d's weakest direction "
        "in m beside rad: the check probes other configurations at another size"),
    'mat_workspace_replaced': (
        'pinlin/files.py',
        '            return {"state_names", "meta"} <= names <= set(_MODEL_ARRAYS)',
        '            return {"state_names", "meta"} <= names',
        "a .mat workspace holding a pinlin model and the user's own variables is replaced"),
    'continuous_angle_wrapped': (
        'pinlin/simulation.py', '    X[:, turning] = C[:, turning]\n', '',
        "a simulated continuous joint's angle wraps at pi (the history jumps by 2 pi, u0's "
        "work and so the energy by 2 pi u0 at every turn)"),
    'partition_in_mixed_units': (
        'pinlin/assembly.py',
        '    scaled = in_one_unit(system, jac)   # the choices and the condition, in one unit',
        '    scaled = jac',
        "the partition pivots and measures Phi_d in m/m beside m/rad: a standing robot's "
        "states and its condition change with its size"),
    'partition_translations_not_preferred': (
        'pinlin/assembly.py', "    weight = np.where(linear_coordinates(system), 1e3, 1.0)",
        "    weight = np.ones(system.nv)",
        "a box balanced on a point keeps its translations as states instead of its rotations"),
    'partition_ties_to_rounding': (
        'pinlin/assembly.py', '    return weight * tie_break(system.nv)', '    return weight',
        "a symmetric robot's legs tie in the partition's pivoted QR and rounding picks its "
        "states (another machine, other states)"),
    'dropped_row_ties_to_rounding': (
        'pinlin/assembly.py', '    diag, piv = pivoted_qr(jac.T * tie_break(jac.shape[0]))',
        '    diag, piv = pivoted_qr(jac.T)',
        "rounding picks which of two equal redundant contact rows is dropped"),
    'velocity_projection_mixed_units': (
        'pinlin/formulations/motion.py',
        '        v, correction = project_velocity(G, v0, None if factors is None else factors[1])',
        '        v, correction = project_velocity(G, v0)',
        "a given velocity is projected to the closest consistent one in m/s beside rad/s "
        "(a floating base's projection changes with its size)"),
    'stacked_velocity_projection_mixed_units': (
        'pinlin/formulations/moving_batch.py', '        factors = unit_factors(system)',
        '        factors = None',
        "a mechanism's stacked kernels project a given velocity in m/s beside rad/s"),
    'simulation_repartition_mixed_units': (
        'pinlin/simulation_ode.py',
        '        G1 = in_one_unit(self.system, G, self.rows)   # as partition() measures it',
        '        G1 = G',
        "the simulation compares Phi_d's condition with a fresh choice's in m/m beside m/rad "
        "and keeps a slider-crank's slider through its singular positions"),
    'trajectory_stacked_condition_mixed_units': (
        'pinlin/trajectory_loops.py',
        '    Gd = in_one_unit(system, lk.jacobian(plan, J[1:last])[:, rows][:, :, dep], rows, dep)',
        '    Gd = lk.jacobian(plan, J[1:last])[:, rows][:, :, dep]',
        "a stacked trajectory measures Phi_d's condition in mixed units after its first point"),
    'trajectory_point_condition_mixed_units': (
        'pinlin/trajectory_loops.py',
        '        condition[k] = (float(np.linalg.cond(in_one_unit(system, G[:, dep], rows, dep)))',
        '        condition[k] = (float(np.linalg.cond(G[:, dep]))',
        "a trajectory assembled point by point measures Phi_d's condition in mixed units"),
    'statics_length_from_the_origin': (
        'pinlin/coordinates.py', '((P - P.mean(axis=0)) ** 2)', '(P ** 2)',
        "a point-mass robot's split takes its joints' distance from the world origin as its "
        "size (the split changes where it stands)"),
    'validate_fixed_loop_step': (
        'pinlin/validate.py', 'max(LOOP_PHASE / fastest, mjcf.MIN_TIME_STEP)', '1e-4',
        "validate steps MuJoCo at a fixed 1e-4 s for every mechanism, whatever its size"),
    'simulation_newton_absolute': (
        'pinlin/simulation_ode.py', 'best = float((np.abs(phi) / self.row_scale).max(initial=0.0))',
        'best = float(np.abs(phi).max(initial=0.0))',
        "the simulation closes the loops to an absolute 1e-14 m, whatever the mechanism's size"),
    'mass_condition_unscaled': (
        'pinlin/conditioning.py', '    return float(np.dot(M.diagonal(), Minv.diagonal()))',
        '    return float(M.trace() * Minv.trace() / M.shape[0])',
        "the mass matrix's condition estimate mixes the coordinates' units (kg and kg*m^2)"),
    'cli_response_feedback_sign': (
        'pinlin/cli_motion.py', '        model = model.closed_loop(gain[0])',
        '        model = model.closed_loop(-gain[0])',
        "pinlin response --feedback closes the loop with the gain's sign flipped"),
    'trajectory_second_order_unchecked': (
        'pinlin/trajectory_model.py', "        _check_second_order_points(self)\n", "",
        "a trajectory file's M, C_damp, K, Bu load without being checked against A and B"),
    'trajectory_rest_drift_kept': (
        'pinlin/trajectory_model.py', "        _check_rest_drift(self)\n", "",
        "a trajectory file's drift at a point at rest loads (and at(k) drops it)"),
    'response_signal_jump_through_e_lost': (
        'pinlin/response.py',
        "xs0 = x0 + std.B @ impulse if signal is not None else x0 - E @ U[0]",
        "xs0 = x0 - E @ U[0] + std.B @ impulse",
        "a signal's step through E (input derivative) starts from the state after it"),
    'spring_wrap_unsaid': (
        'pinlin/simulation_ode.py', "        if beyond.size:\n", "        if False:\n",
        "simulate says nothing when a continuous joint's spring passes its wrap"),
    'validity_order_fits_parted_motions': (
        'pinlin/validity_sweep.py',
        "    elif saturated.any() and np.any(~ok[:int(np.argmax(saturated))]):",
        "    elif False:",
        "validity fits an order to errors that jump from the noise to parted motions"),
    'cli_numbers_with_underscores': (
        'pinlin/fields.py', '    if "_" in text or not text.isascii():', '    if False:',
        "the command line and CSV files read 1_0 as 10 (Python's float)"),
    'array_repr_in_messages': (
        'pinlin/fields.py', "    if isinstance(x, np.ndarray) and (x.ndim > 1 or x.size > 6):",
        "    if False:", "a user's array is shown in an error message by numpy's multi-line repr"),
    'phi1_without_series': (
        'pinlin/response.py', "    far = np.abs(z) >= PHI1_SERIES\n", "    far = z != 0\n",
        "the modal response divides expm1(z) by a subnormal z (a step of 1e-310 s)"),
    'defective_pair_first_order': (
        'pinlin/eigensolvers.py',
        "    return np.where(gaps[:, 1] > 2.0 * reach, np.minimum(first, reach), first)",
        "    return first",
        "modal's accuracy warning takes first order for a defective pair (critical damping)"),
    'drift_velocity_unchecked': (
        'pinlin/linear_model.py', "        check_drift(self)\n", "",
        "a model file's drift f0 loads whatever its dq' = v0 half says"),
    'validity_amplitude_in_metres': (
        'pinlin/validity.py', "length, w = _unit_weights(system, model)",
        "length, w = _unit_weights(system, model)\n    w = np.ones_like(w)",
        "validity measures a length's amplitude and error in metres beside radians"),
}


def copy_checkout(dest: Path) -> None:
    """The last commit of the checkout (``git archive HEAD``), unpacked into ``dest``: the
    result does not depend on edits in progress."""
    archive = subprocess.run(["git", "archive", "--format=tar", "HEAD"], cwd=ROOT,
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)


def run_one(name: str, work: Path) -> tuple[str, str, float]:
    """(outcome, first failing test or '', seconds) for mutation ``name`` in a fresh copy."""
    rel, old, new, _ = MUTATIONS[name]
    path = work / rel
    original = path.read_text()
    if original.count(old) != 1:
        return "stale", f"snippet found {original.count(old)} times in {rel}", 0.0
    path.write_text(original.replace(old, new))
    env = {**os.environ, "PYTHONPATH": str(work), "PYTHONDONTWRITEBYTECODE": "1"}
    start = time.perf_counter()
    try:
        res = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p",
                              "no:cacheprovider", "-W", "ignore"], cwd=work, env=env,
                             capture_output=True, text=True, check=False, timeout=RUN_TIMEOUT)
    except subprocess.TimeoutExpired:
        path.write_text(original)
        return "hung", f"stopped after {RUN_TIMEOUT:.0f} s", time.perf_counter() - start
    seconds = time.perf_counter() - start
    path.write_text(original)
    failed = [ln.split(" ")[1] for ln in res.stdout.splitlines()
              if ln.startswith(("FAILED ", "ERROR "))]
    if res.returncode == 0:
        return "survived", "", seconds
    return "caught", failed[0] if failed else f"exit {res.returncode}", seconds


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", choices=[[], *MUTATIONS], metavar="NAME")
    parser.add_argument("--jobs", type=int, default=1,
                        help="mutations run at once, each in its own copy (default 1)")
    args = parser.parse_args(argv)
    names = args.names or list(MUTATIONS)
    jobs = max(1, args.jobs)
    with tempfile.TemporaryDirectory(prefix="pinlin-mutation-") as tmp:
        copies: queue.Queue[Path] = queue.Queue()
        for j in range(jobs):
            work = Path(tmp) / f"copy{j}"
            work.mkdir()
            copy_checkout(work)
            copies.put(work)
        first = Path(tmp) / "copy0"
        env = {**os.environ, "PYTHONPATH": str(first), "PYTHONDONTWRITEBYTECODE": "1"}
        baseline = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p",
                                   "no:cacheprovider", "-W", "ignore"], cwd=first, env=env,
                                  capture_output=True, text=True, check=False)
        if baseline.returncode != 0:
            sys.exit("the unmutated copy fails its own tests: fix that first\n"
                     + baseline.stdout[-2000:])

        def planted(name: str) -> tuple[str, str, str, float]:
            work = copies.get()    # a copy no other mutation is using
            try:
                outcome, where, seconds = run_one(name, work)
            finally:
                copies.put(work)
            print(f"{name:36s} {outcome:9s} {seconds:6.1f} s  {where}", flush=True)
            return name, outcome, where, seconds

        with ThreadPoolExecutor(jobs) as pool:
            results = list(pool.map(planted, names))   # in the list's order
    caught = sum(r[1] == "caught" for r in results)
    if len(names) < len(MUTATIONS):
        print(f"{caught} of {len(results)} caught (a subset: the report is written only for "
              "the whole list)")
        return
    lines = [
        "# Mutation check: do the tests fail when the code is wrong?",
        "",
        "Produced by `python validation/mutation.py`: each bug below is planted alone in a "
        "temporary copy of the checkout and the whole suite is run against it (stopping at "
        "the first failure).",
        "",
        f"**Score: {caught} of {len(results)} planted bugs caught.**",
        "",
        "| mutation | the bug | outcome | first failing test |",
        "|---|---|---|---|",
    ]
    for name, outcome, where, _ in results:
        lines.append(f"| {name} | {MUTATIONS[name][3]} | {outcome} | {where} |")
    write_text_atomic(REPORT, "\n".join(lines) + "\n")
    print(f"{caught} of {len(results)} caught; report written to {REPORT}")


if __name__ == "__main__":
    main()
