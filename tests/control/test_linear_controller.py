"""linear_controller: a linear agent as an LTI map y -> a (for loop analysis), against the agent's own steps, and the
roll agent's loop gain in the wind's band against the precision of its intention (docs/control.md, the roll axis)."""

import numpy as np

from attend.control import (ActiveInferenceController, GenerativeModel, GenerativeProcess, closed_loop_spectral_radius,
                            linear_controller, markov_parameters)
from attend.control.roll import roll_matrices
from attend.models.linear import zero_order_hold

DT = 1.0 / 120.0
C2 = np.array([[1.0, 0.0], [1.0, 0.0]])


def roll_agent(cause_log_precision, data_motion="generalised", target=0.0):
    """The roll agent of benchmarks/bench_control.py at the tuned point of exp(8) (w, Pi_w, kappa, s =
    12.3 rad/s, 4.1e8, 5.2e4, 0.006 s), with its intention held at precision exp(cause_log_precision)."""
    w, Pi_w, kappa, s = 12.3, 4.1e8, 5.2e4, 0.006
    A_m = np.array([[0.0, 1.0], [-w**2, -2.0 * w]])
    B_m = np.array([[0.0, 0.0, 0.0], [w**2, 2.0 * w, 1.0]])
    model = GenerativeModel.linear(A_m, B_m, C2, sensor_precision=1.0 / 0.002**2, process_precision=Pi_w,
                                   cause_prior_precision=np.exp(cause_log_precision),
                                   cause_prior=[target, 0.0, 0.0], kernel_width=s, embedding_order=2, cause_order=1)
    A, B = roll_matrices()
    G = markov_parameters(A, B, C2, np.zeros((2, 1)), 3, hold=DT)
    return ActiveInferenceController(model, DT, action_gain=kappa, action_jacobian=G, sensory_orders=2,
                                     data_motion=data_motion)


def test_the_map_reproduces_the_agents_steps():
    for motion in ("held", "generalised"):
        agent = roll_agent(8.0, motion)
        A, B, C, D = linear_controller(agent)
        rng = np.random.default_rng(0)
        ys = np.cumsum(rng.standard_normal((300, 2)) * 1e-3, axis=0)
        Z0 = np.concatenate([agent.generalised_states, agent.generalised_causes, agent.action])
        window = A.shape[0] - Z0.size  # the embedding window's length (W m)
        q = np.concatenate([np.tile(ys[0], window // 2), Z0])  # the first sample's clamp, Z[0]
        taken, mapped = [], []
        for y in ys:
            taken.append(agent.step(y)[0])
            mapped.append((C @ q + D @ y)[0])
            q = A @ q + B @ y
        taken, mapped = np.array(taken), np.array(mapped)
        assert np.abs(taken - mapped).max() <= 1e-9 * np.abs(taken).max()


def test_its_closed_loop_has_the_loops_spectral_radius():
    agent = roll_agent(8.0)
    A, B = roll_matrices()
    world = GenerativeProcess.linear(A, B, C2)
    Ac, Bc, Cc, Dc = linear_controller(agent)
    Ad, Bd = zero_order_hold(A, B, DT)
    loop = np.block([[Ad + Bd @ Dc @ C2, Bd @ Cc], [Bc @ C2, Ac]])
    assert np.isclose(np.abs(np.linalg.eigvals(loop)).max(), closed_loop_spectral_radius(world, agent), rtol=1e-9)


def gain(agent, omega):
    """|K(e^{j omega dt})|: the action per radian of roll read by both sensors."""
    A, B, C, D = linear_controller(agent)
    z = np.exp(1j * omega * DT)
    return abs((C @ np.linalg.solve(z * np.eye(A.shape[0]) - A, B) + D).sum())


def test_a_stiffer_intention_raises_the_reflexs_gain_in_the_winds_band():
    # at exp(8) the belief about the target yields to the roll at the wind's frequencies, and the reflex acts on what
    # is left; held as precisely as a sensor (1 / 0.002^2), the loop gain at 1-5 rad/s rises by 1.46-1.59x
    # (measured: 23.7e3 -> 34.5e3 per rad at 1 rad/s, 5.5e3 -> 8.7e3 at 5 rad/s), and at crossover (40 rad/s)
    # by 1.22x (5.3e3 -> 6.5e3)
    soft, stiff = roll_agent(8.0), roll_agent(-2 * np.log(0.002))
    for omega in (1.0, 5.0):
        assert gain(stiff, omega) > 1.35 * gain(soft, omega)
    assert gain(stiff, 40.0) < 1.3 * gain(soft, 40.0)


def arm_agent(cause_log_precision):
    """The two-link arm's agent of benchmarks/bench_control.py at its tuned point of exp(8) (w, Pi_w, kappa, s =
    11.5 rad/s, 2.1e6, 533, 12.2 ms; the reference's acceleration a cause, the held column, attending orders 0..2),
    with dy~/da fixed at rest at the step's target (-0.6, 0.8) rad and the intention at precision
    exp(cause_log_precision); without the gravity feed-forward."""
    from attend.control import arm

    target = np.array([-0.6, 0.8])
    model = arm.critically_damped_model(
        11.5, sensor_std=0.002, process_precision=2.1e6, kernel_width=0.0122,
        cause_prior=lambda t: np.concatenate([target, np.zeros(10)]), cause_prior_precision=np.exp(cause_log_precision),
        embedding_order=2, initial_angles=target, reference_acceleration=True)
    G = arm.ArmActionJacobian(arm.ArmParameters(), 2, hold=0.01)(np.concatenate([target, [0.0, 0.0]]), None, None)
    return ActiveInferenceController(model, 0.01, action_gain=533.0, n_actions=2, action_jacobian=G, sensory_orders=2)


def test_on_the_arm_a_stiffer_intention_raises_each_joints_low_frequency_gain():
    # the arm's agent at exp(8): its believed target yields to the joint angles (0.4-1.2 rad per rad at 1-10 rad/s,
    # --loop-shape --plant arm); held at 1 / 0.002^2 the gain from a joint's angle to its own torque at 1 rad/s rises
    # about 2.5x (shoulder) and 2x (elbow)
    def joint_gain(agent, joint, omega):
        A, B, C, D = linear_controller(agent)
        z = np.exp(1j * omega * 0.01)
        K = C @ np.linalg.solve(z * np.eye(A.shape[0]) - A, B) + D  # (torques, sensors [q1, q2, q1, q2])
        return abs(K[joint, joint::2].sum())
    soft, stiff = arm_agent(8.0), arm_agent(-2 * np.log(0.002))
    for joint in (0, 1):
        assert joint_gain(stiff, joint, 1.0) > 1.6 * joint_gain(soft, joint, 1.0)
