import sys, os
sys.path.insert(0, os.getcwd())
import json, sys
import os; sys_path_fix = __import__("sys").path.insert(0, os.getcwd())
from multiprocessing import Pool
import hyst_gym
from experiments.diagnose_concealed import run_one
out = sys.argv[1]
jobs = [("own", ch, eff, True, seed, 5000) for eff in ("thermal_drift", "none")
        for ch in ("magnetization", "displacement", "both") for seed in (100, 101, 102)]
print(hyst_gym.__file__, flush=True)
with Pool(int(sys.argv[2])) as pool:
    rows = pool.map(run_one, jobs)
json.dump(rows, open(out, "w"), indent=1, default=str)
for r in rows:
    print(r["effect"], r["channels"], r["seed"], r["verdict"], r["tied"], r["outcome"], flush=True)
