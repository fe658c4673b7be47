#!/usr/bin/env bash
# A one-node Slurm cluster on localhost (Debian's slurm-wlm and munge), then a sweep
# submitted with the script `brainshift sweep emit-slurm` writes, waited for and collected.
# Usage: .ci/slurm.sh BRAINSHIFT_BIN   (needs root for apt-get and the daemons)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "${1:?usage: .ci/slurm.sh BRAINSHIFT_BIN}")

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null
fi

work=$(mktemp -d /tmp/bs-slurm.XXXXXX)
state=$work/state
mkdir -p "$state/ctld" "$state/d" /run/munge /var/log/munge /var/lib/munge
chown -R munge: /run/munge /var/log/munge /var/lib/munge /etc/munge 2>/dev/null || true
[ -s /etc/munge/munge.key ] || { dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key 2>/dev/null; chown munge: /etc/munge/munge.key; chmod 400 /etc/munge/munge.key; }
pgrep -x munged >/dev/null || runuser -u munge -- /usr/sbin/munged

host=$(hostname -s)
cpus=$(nproc)
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
conf=$work/slurm.conf
cat > "$conf" <<CONF
ClusterName=bs-ci
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/d
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/builtin
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$conf
/usr/sbin/slurmctld -f "$conf"
/usr/sbin/slurmd -f "$conf"
cleanup() {
  [ -f "$work/slurmd.pid" ] && kill "$(cat "$work/slurmd.pid")" 2>/dev/null || true
  [ -f "$work/slurmctld.pid" ] && kill "$(cat "$work/slurmctld.pid")" 2>/dev/null || true
}
trap cleanup EXIT
for _ in $(seq 60); do
  sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed)' && break
  sleep 1
done
if ! sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed)'; then
  echo "slurm did not come up within 60 s; logs:" >&2
  tail -n 30 "$work"/slurmctld.log "$work"/slurmd.log >&2 || true
  exit 1
fi
sinfo

base=$(realpath fixtures/cube/uniaxial-t4.toml)
cat > "$work/sweep.toml" <<SWEEP
base = "$base"
[[axis]]
key = "region.material.youngs_modulus"
values = [1500.0, 3000.0, 6000.0]
[[axis]]
key = "boundary.3.displacement.z"
values = [-0.05, -0.1]
SWEEP
"$BIN" sweep plan "$work/sweep.toml" --out "$work/sweep"
"$BIN" sweep emit-slurm "$work/sweep" --max-parallel 2 --time 00:05:00 --cpus-per-task 1
job=$(timeout 600 sbatch --parsable --wait "$work/sweep/sweep.slurm")
echo "slurm job $job finished"
"$BIN" sweep collect "$work/sweep" | tee "$work/collect.txt"
grep -q "6 rows: 6 ok, 0 failed, 0 missing" "$work/collect.txt"
echo "slurm: 1 passed, 0 failed"
