"""A servo loop driving a simulated robot: the paper scenario's Afma6, its camera as the detector, 100 Hz."""

import servostack as ss

scenario = ss.Scenario.from_file("assets/scenarios/paper_afma6.toml")  # run from the repository's root
world, servo = scenario.experiment(), ss.VisualServo.from_scenario(scenario)
q, dt = world.start, scenario.period
for k in range(10_000):
    v = servo.step(k * dt, world.corners(q), q)  # corners (px) and joints in, joint velocity out
    if servo.converged:
        break
    q = q + v * dt  # a real loop sends v to the drives here
print(f"converged={servo.converged} after {k * dt:.2f} s;", [(e["iteration"], e["kind"], e["task_name"]) for e in servo.events])
