"""A first walk from Python: run it, read its log as a DataFrame, plot one actuator torque."""
import matplotlib.pyplot as plt

import humanoid_sim as hs

run = hs.run_walk("sim3_zmp", engine="mujoco")
df = run.log.to_pandas()
df["T.T3 [N m]"].plot(title=f"sim3_zmp on MuJoCo ({run.status.value}): actuator torque T3", ylabel="T3 [N m]")
plt.savefig("first_walk_T3.png")
