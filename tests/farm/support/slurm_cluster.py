"""A single-node Slurm cluster on localhost for the farm tests: munged, slurmctld and slurmd
started in a temporary folder with a generated slurm.conf (free ports, the node's own CPUs),
and stopped again. Needs Debian's slurm-wlm and munge (tools/install_deps.sh) and root
(slurmd runs the tasks as their submitter)."""

import os
import shutil
import socket
import subprocess
import time


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def missing():
    """Why a cluster cannot start here (None: it can)."""
    for tool in ("munged", "slurmctld", "slurmd", "sbatch", "squeue", "scontrol"):
        if shutil.which(tool) is None:
            return f"{tool} not found: install slurm-wlm and munge (tools/install_deps.sh)"
    if os.geteuid() != 0:
        return "slurmd must run as root here (the tests start the cluster themselves)"
    return None


class Cluster:
    """`with Cluster(folder) as c:` runs commands against the cluster through c.env."""

    def __init__(self, folder):
        self.folder = str(folder)
        self.env = dict(os.environ, SLURM_CONF=os.path.join(self.folder, "slurm.conf"))

    def _path(self, *parts):
        return os.path.join(self.folder, *parts)

    def __enter__(self):
        for sub in ("munge", "state", "spool", "log"):
            os.makedirs(self._path(sub), exist_ok=True)
        os.chmod(self._path("munge"), 0o700)
        key = self._path("munge", "munge.key")
        with open(key, "wb") as f:
            f.write(os.urandom(1024))
        os.chmod(key, 0o400)
        self.socket = self._path("munge", "munge.socket")
        subprocess.run(["munged", "-f", f"--socket={self.socket}", f"--key-file={key}",
                        f"--log-file={self._path('log', 'munged.log')}",
                        f"--pid-file={self._path('munge', 'munged.pid')}",
                        f"--seed-file={self._path('munge', 'seed')}"], check=True)
        # The node by its short host name (what slurmd calls itself), reached at 127.0.0.1 so
        # that nothing depends on the host name resolving.
        host = socket.gethostname().split(".")[0]
        conf = f"""ClusterName=airlighttest
SlurmctldHost={host}(127.0.0.1)
AuthType=auth/munge
AuthInfo=socket={self.socket}
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
SlurmctldPort={_free_port()}
SlurmdPort={_free_port()}
StateSaveLocation={self._path('state')}
SlurmdSpoolDir={self._path('spool')}
SlurmctldPidFile={self._path('slurmctld.pid')}
SlurmdPidFile={self._path('slurmd.pid')}
SlurmctldLogFile={self._path('log', 'slurmctld.log')}
SlurmdLogFile={self._path('log', 'slurmd.log')}
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
MinJobAge=600
NodeName={host} NodeAddr=127.0.0.1 CPUs={os.cpu_count()} State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
"""
        with open(self.env["SLURM_CONF"], "w") as f:
            f.write(conf)
        subprocess.run(["slurmctld"], env=self.env, check=True)
        subprocess.run(["slurmd", "-N", host], env=self.env, check=True)
        deadline = time.time() + 60
        while time.time() < deadline:
            out = subprocess.run(["sinfo", "-h", "-o", "%t"], env=self.env, capture_output=True, text=True)
            if out.returncode == 0 and out.stdout.strip() in ("idle", "mix", "alloc"):
                return self
            time.sleep(0.5)
        self.__exit__(None, None, None)
        logs = []
        for name in ("slurmctld.log", "slurmd.log"):
            try:
                with open(self._path("log", name)) as f:
                    logs.append(f"--- {name}:\n" + "".join(f.readlines()[-15:]))
            except OSError:
                pass
        raise RuntimeError("the test cluster's node did not come up:\n" + "\n".join(logs))

    def wait(self, job, timeout=600):
        """Waits until no task of _job_ is pending or running; returns scontrol's record of
        each of its tasks (dicts of its key=value fields)."""
        deadline = time.time() + timeout
        while time.time() < deadline:
            out = subprocess.run(["squeue", "-h", "-j", str(job)], env=self.env, capture_output=True, text=True)
            if out.returncode == 0 and not out.stdout.strip():
                break
            time.sleep(1.0)
        else:
            raise TimeoutError(f"job {job} still running after {timeout} s")
        out = subprocess.run(["scontrol", "-o", "show", "job", str(job)], env=self.env, capture_output=True,
                             text=True, check=True)
        return [dict(field.split("=", 1) for field in line.split() if "=" in field)
                for line in out.stdout.splitlines() if line.strip()]

    def __exit__(self, *exc):
        for pid_file in ("slurmd.pid", "slurmctld.pid", os.path.join("munge", "munged.pid")):
            try:
                with open(self._path(pid_file)) as f:
                    pid = int(f.read().strip())
                os.kill(pid, 15)
            except (OSError, ValueError):
                pass
        time.sleep(0.5)
        return False
