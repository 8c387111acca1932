"""Multi-process training under torchrun: which process this is, its device and seed, and the few collectives the
training loop needs (DistributedDataParallel does the gradient averaging).

torchrun starts one process per device and tells each its place through the environment (``WORLD_SIZE``,
``RANK``, ``LOCAL_RANK``, ``MASTER_ADDR``, ``MASTER_PORT``). Outside torchrun, or with a single process, every
function here is the identity or a no-op, so a single-process run takes exactly the path it takes without them.
"""

from __future__ import annotations

import contextlib
import hashlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from datetime import timedelta

import torch
import torch.distributed as dist
from torch import nn
from torch.nn.parallel import DistributedDataParallel

from darksynth.errors import DarksynthError
from darksynth.seeding import derive_seed

__all__ = [
    "SINGLE_PROCESS",
    "Ranks",
    "all_agree",
    "all_gather_tensor",
    "all_state_digests",
    "backend_for",
    "generator_key",
    "per_process_batch",
    "process_group",
    "process_seed",
    "rank_device",
    "ranks_from_environment",
    "state_digest",
    "wrap_model",
]


@dataclass(frozen=True)
class Ranks:
    """This process's place in a run: its ``rank`` among ``world_size`` processes, and ``local_rank`` among those
    on its machine (the index of its GPU)."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        """Rank 0: the process that validates and writes files."""
        return self.rank == 0


SINGLE_PROCESS = Ranks()


def _integer(environment: Mapping[str, str], name: str, default: str | None = None) -> int:
    text = environment.get(name, default)
    if text is None:
        raise DarksynthError(f"torchrun environment: WORLD_SIZE is set but {name} is not")
    try:
        return int(text)
    except ValueError:
        raise DarksynthError(f"torchrun environment: {name}={text!r} is not an integer") from None


def ranks_from_environment(environment: Mapping[str, str]) -> Ranks:
    """This process's ranks as torchrun sets them (``WORLD_SIZE``, ``RANK``, ``LOCAL_RANK``).

    Without ``WORLD_SIZE``, or with a world of one process, the run is a plain single-process run.

    Raises:
        DarksynthError: the variables are present but not consistent integers.
    """
    if "WORLD_SIZE" not in environment:
        return SINGLE_PROCESS
    world_size = _integer(environment, "WORLD_SIZE")
    rank = _integer(environment, "RANK")
    local_rank = _integer(environment, "LOCAL_RANK", default="0")
    if world_size < 1 or not 0 <= rank < world_size or local_rank < 0:
        raise DarksynthError(
            f"torchrun environment: RANK={rank}, LOCAL_RANK={local_rank}, WORLD_SIZE={world_size} are inconsistent"
        )
    if world_size == 1:
        return SINGLE_PROCESS
    return Ranks(rank=rank, world_size=world_size, local_rank=local_rank)


def rank_device(device: str, ranks: Ranks) -> torch.device:
    """The device this process trains on: ``device`` itself for a single process; under torchrun, a CUDA
    ``device`` means this process's own GPU, ``cuda:LOCAL_RANK``.

    Raises:
        DarksynthError: a GPU index given under torchrun (each process picks its own), or no such GPU.
    """
    requested = torch.device(device)
    if not ranks.distributed or requested.type != "cuda":
        return requested
    if requested.index is not None:
        raise DarksynthError(f"--device {device}: under torchrun give --device cuda; each process uses cuda:LOCAL_RANK")
    if not torch.cuda.is_available() or ranks.local_rank >= torch.cuda.device_count():
        raise DarksynthError(f"--device cuda: process {ranks.rank} has no GPU cuda:{ranks.local_rank}")
    return torch.device("cuda", ranks.local_rank)


def backend_for(device: torch.device) -> str:
    """``nccl`` between GPUs, ``gloo`` between CPU processes."""
    return "nccl" if device.type == "cuda" else "gloo"


def process_seed(seed: int, ranks: Ranks) -> int:
    """The seed of this process's data generator: the run seed on rank 0 (so that a single-process run is rank 0
    of a world of one), a seed derived from the run seed and the rank on the others."""
    if ranks.rank == 0:
        return seed
    return derive_seed("darksynth", "train", seed, "rank", ranks.rank)


def per_process_batch(batch: int, ranks: Ranks) -> int:
    """Clips each process draws per step: the configured (global) batch split evenly over the processes.

    DistributedDataParallel averages the processes' gradients, and every loss term is a mean over equally sized
    per-process batches, so a step follows the gradient of the mean loss over the whole ``batch``.

    Raises:
        DarksynthError: ``batch`` is not a multiple of the number of processes.
    """
    if batch % ranks.world_size:
        raise DarksynthError(f"--batch {batch} cannot be split evenly over {ranks.world_size} processes")
    return batch // ranks.world_size


def generator_key(rank: int) -> str:
    """The checkpoint tensor holding a rank's data-generator state (rank 0's is the single-process key)."""
    return "generator" if rank == 0 else f"generator.rank{rank}"


@contextlib.contextmanager
def process_group(ranks: Ranks, device: torch.device, *, timeout: timedelta | None = None) -> Iterator[None]:
    """Join the torchrun process group (``MASTER_ADDR`` and ``MASTER_PORT`` from the environment) for the block,
    and leave it afterwards, even on an error. Nothing happens for a single process.

    Raises:
        DarksynthError: the group cannot be formed (another group already exists, or the rendezvous fails).
    """
    if not ranks.distributed:
        yield
        return
    if dist.is_initialized():
        raise DarksynthError("a torch.distributed process group already exists in this process")
    if device.type == "cuda":
        torch.cuda.set_device(device)
    try:
        dist.init_process_group(
            backend_for(device), rank=ranks.rank, world_size=ranks.world_size, timeout=timeout, init_method="env://"
        )
    except (RuntimeError, ValueError) as error:
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise DarksynthError(f"cannot join the torchrun process group ({first_line})") from None
    try:
        yield
    finally:
        dist.destroy_process_group()


def _communication_device() -> torch.device:
    # NCCL moves only CUDA tensors (on the device set by process_group); gloo moves CPU tensors.
    return torch.device("cuda", torch.cuda.current_device()) if dist.get_backend() == "nccl" else torch.device("cpu")


def wrap_model(module: nn.Module, device: torch.device, *, find_unused_parameters: bool = False) -> nn.Module:
    """``module`` wrapped in DistributedDataParallel inside a process group, ``module`` itself outside one.

    Args:
        module: The network, already on ``device``. Rank 0's parameters and buffers are copied to the other
            processes here, and only here: the DEN's buffers (the statistics standardisation) are fixed before
            training, so they are not re-sent before every step.
        device: This process's device (:func:`rank_device`).
        find_unused_parameters: Some parameters get no gradient in a step (a decoder whose loss weight is 0).
    """
    if not dist.is_initialized():
        return module
    return DistributedDataParallel(
        module,
        device_ids=[device.index] if device.type == "cuda" else None,
        forward_sync_buffers=False,
        find_unused_parameters=find_unused_parameters,
    )


def all_gather_tensor(tensor: torch.Tensor) -> list[torch.Tensor]:
    """Every process's ``tensor`` (same shape and dtype on all), on the CPU, in rank order; ``[tensor]`` outside
    a process group."""
    if not dist.is_initialized():
        return [tensor]
    carrier = _communication_device()
    sent = tensor.detach().to(carrier)
    received = [torch.empty_like(sent) for _ in range(dist.get_world_size())]
    dist.all_gather(received, sent)
    return [item.cpu() for item in received]


def all_agree(ok: bool) -> bool:
    """True when every process says ``ok`` (a collective: all processes must call it at the same point), so that
    one process's failure stops all of them instead of leaving the others waiting for it."""
    if not dist.is_initialized():
        return ok
    flag = torch.tensor([int(ok)], device=_communication_device())
    dist.all_reduce(flag, op=dist.ReduceOp.MIN)
    return bool(flag.item())


def state_digest(module: nn.Module) -> str:
    """SHA-256 of a module's state (names, dtypes, shapes and bytes of every parameter and buffer, in
    ``state_dict`` order): equal digests on all processes show that they hold the same network."""
    digest = hashlib.sha256()
    for name, tensor in module.state_dict().items():
        value = tensor.detach().cpu().contiguous()
        digest.update(f"{name}:{value.dtype}:{tuple(value.shape)}:".encode())
        digest.update(value.reshape(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def all_state_digests(module: nn.Module) -> list[str]:
    """Every process's :func:`state_digest` of ``module``, in rank order (a collective)."""
    digest = torch.tensor(list(bytes.fromhex(state_digest(module))), dtype=torch.uint8)
    return [bytes(item.tolist()).hex() for item in all_gather_tensor(digest)]
