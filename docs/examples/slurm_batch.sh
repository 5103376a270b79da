#!/bin/bash
# dvs batch as a Slurm job array: `sbatch slurm_batch.sh` from the folder the jobs file's relative paths start
# at. Array task I of N runs the jobs whose index is I modulo N, so the tasks split the file with no
# coordinator, and a task run again skips the jobs it already finished. JOBS and MODEL override the two paths
# below; dvs must be on PATH. The array's size is the number of GPUs to keep busy.
#SBATCH --job-name=dvs-batch
#SBATCH --array=0-7
#SBATCH --gpus=1
#SBATCH --output=dvs-batch-%A_%a.log
set -euo pipefail
JOBS="${JOBS:-jobs.jsonl}"
MODEL="${MODEL:-/models/CogVideoX-5b-I2V}"
exec dvs batch "$JOBS" --model "$MODEL" --vae-tiling --progress json \
    --shard "${SLURM_ARRAY_TASK_ID}/${SLURM_ARRAY_TASK_COUNT}"
