#!/bin/bash
# A limot evaluation suite as a Slurm array job: one task per shard, all
# writing into one shared suite directory, then one merge.
#
#   sbatch --array=1-8 scripts/slurm-suite.sh            # 8 shards
#   # when every task has finished (or: sbatch --dependency=afterok:JOBID ...):
#   limot report --merge "$OUT"/results-shard-*-of-8.json
#
# Shard K of N takes sequences K-1, K-1+N, ... of the family-major list
# (families in the given order, seeds within each), so N may exceed the
# number of cores of any one node; a shard with no sequence writes an empty
# results file, which the merge accepts. The figures do not depend on how
# the suite was split or on --jobs; per-stage times do (use --jobs 1 and
# whole nodes for timing). Kubernetes indexed Jobs (JOB_COMPLETION_INDEX
# + 1) and GNU parallel (`parallel limot eval suite ... --shard {}/8 ::: $(seq 8)`)
# run the same command.
#SBATCH --job-name=limot-suite
#SBATCH --cpus-per-task=2
#SBATCH --time=02:00:00
set -euo pipefail
OUT=${OUT:-reports/suite}
N=${SLURM_ARRAY_TASK_COUNT:?run with sbatch --array=1-N}
K=${SLURM_ARRAY_TASK_ID:?run with sbatch --array=1-N}
exec limot eval suite \
  --seeds 1,2,3,4 --duration 30 --out "$OUT" --shard "$K/$N" --jobs "${SLURM_CPUS_PER_TASK:-1}"
