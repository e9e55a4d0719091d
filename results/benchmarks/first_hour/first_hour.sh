#!/usr/bin/env bash
# The first hour, again: a fresh clone of main, a fresh venv (no system packages), the README's two
# commands, then pytest twice more; under the load of the round's final recomputation (3 processes), after the hostile pass's fixes.
set -u
cd /work/scratch/fh
rm -rf clone venv figures
git clone -q /work/main clone
python -m venv venv
. venv/bin/activate
cd clone
out=/work/scratch/fh/first_hour.txt
{
echo "# /work/scratch/fh/first_hour.sh: a fresh clone of main (commit below), a fresh venv (python -m venv, no system packages),"
echo "# the README's two commands, then pytest twice more; under the load of the round's final recomputation (3 processes), after the hostile pass's fixes"
git log --oneline -1
} > $out
run() {  # run NAME LOG COMMAND
  local name="$1" log="$2"; shift 2
  uptime >> $out
  local start=$SECONDS
  bash -c "$*" > "$log" 2>&1
  echo "$name exit $? in $((SECONDS - start)) s" >> $out
}
run "command 1" /work/scratch/fh/cmd1.log 'pip install . && ilc-steering reproduce --plots figures'
run "command 2" /work/scratch/fh/cmd2.log 'pip install torch==2.13.0 && pip install ".[rl,rl-jax,bo,highway,mujoco,ray,rosbags,test]" && pytest'
run "pytest run 2" /work/scratch/fh/pytest2.log 'pytest'
run "pytest run 3" /work/scratch/fh/pytest3.log 'pytest'
uptime >> $out
if grep -qi "Unknown pytest.mark" /work/scratch/fh/cmd2.log /work/scratch/fh/pytest2.log /work/scratch/fh/pytest3.log; then echo "unknown-mark warning FOUND" >> $out; else echo "no unknown-mark warning" >> $out; fi
for f in cmd2 pytest2 pytest3; do tail -n 1 /work/scratch/fh/$f.log >> $out; done
echo "## command 1 (pip install . && ilc-steering reproduce --plots figures): its last lines" >> $out
grep -E "compiling|^\| experiment" /work/scratch/fh/cmd1.log >> $out
echo FH-DONE >> $out
