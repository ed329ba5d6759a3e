"""Process-group plumbing for training: torchrun's env:// ranks, a resumable sampler, a sync check.

Under ``torchrun`` every process sees RANK, WORLD_SIZE, LOCAL_RANK, MASTER_ADDR and
MASTER_PORT; :func:`setup_distributed` joins the group with NCCL on CUDA and gloo on the CPU.
Without them (plain ``mna train``) it returns a one-process context and no group exists.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import NoReturn

import torch
import torch.distributed as dist
from torch import nn
from torch.utils.data import DistributedSampler

from mna.fit import resolve_device


@dataclass
class Distributed:
    rank: int
    world: int
    local_rank: int
    device: torch.device

    @property
    def active(self) -> bool:
        return self.world > 1

    @property
    def main(self) -> bool:
        return self.rank == 0


def setup_distributed(device_name: str) -> Distributed:
    """Join the process group torchrun describes (env://), or run alone without one."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return Distributed(0, 1, 0, resolve_device(device_name))
    rank, local = int(os.environ["RANK"]), int(os.environ.get("LOCAL_RANK", "0"))
    device = resolve_device(device_name)
    if device.type == "cuda":
        device = torch.device("cuda", local)
        torch.cuda.set_device(device)
    if not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo", init_method="env://")
    return Distributed(rank, world, local, device)


def teardown_distributed() -> None:
    """Leave the process group, if any (every rank, success or not)."""
    if dist.is_initialized():
        dist.destroy_process_group()


def end_rank(code: int) -> NoReturn:
    """End a rank's process with ``code`` without interpreter finalization.

    Gloo's worker threads outlive ``destroy_process_group`` and free a finished collective's
    work object a moment after the caller has its result. When that is a rank's last
    collective and the rank is quick to exit (two ranks on two busy cores: about 1 run in
    10), the worker frees the work's tensors during ``Py_Finalize``, must take the GIL,
    cannot, and aborts the process ("terminate called without an active exception", SIGABRT)
    after all the work was done. Every output is already written through temporary files
    and renames by then, so skipping finalization loses nothing; the streams are flushed.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


class ResumableSampler(DistributedSampler):
    """DistributedSampler that can start ``start`` positions into its epoch (mid-epoch resume)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.start = 0

    def __iter__(self):
        return iter(list(super().__iter__())[self.start:])

    def __len__(self) -> int:
        return self.num_samples - self.start


def rank_param_divergence(model: nn.Module, ctx: Distributed) -> float:
    """Largest |parameter difference| between any rank and rank 0 (0 when alone)."""
    if not ctx.active:
        return 0.0
    flat = torch.cat([p.detach().reshape(-1).float() for p in model.parameters()])
    ref = flat.clone()
    dist.broadcast(ref, 0)
    diff = (flat - ref).abs().max().reshape(1)
    dist.all_reduce(diff, op=dist.ReduceOp.MAX)
    return float(diff)
