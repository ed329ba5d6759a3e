"""Training: overfitting lowers the Chamfer, mid-epoch resume repeats an uninterrupted run, DDP ranks agree."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from mna import datasets, train_config
from mna.conditional import ConditionalAtlas
from mna.reconstruct import evaluate_items, reduce_mean
from mna.train import train


def _cfg(root, out, **overrides) -> train_config.TrainConfig:
    cfg = train_config.tiny()
    cfg.data.root, cfg.out, cfg.device = str(root), str(out), "cpu"
    for key, value in overrides.items():
        setattr(cfg, key, value)
    return cfg.validate()


def _train_chamfer(model, cfg) -> float:
    ds = datasets.build(cfg, "train")
    rows = evaluate_items(model, ds, list(range(len(ds))), cfg, points=1000, full=False)
    return reduce_mean(rows, ("chamfer_pcl",))["chamfer_pcl"]


def test_overfitting_four_shapes_lowers_chamfer_5x(meshes_root, tmp_path):
    cfg = _cfg(meshes_root, tmp_path / "run", epochs=150, lr=3e-3, lr_milestones=[105, 135])
    torch.manual_seed(cfg.seed)
    before = _train_chamfer(ConditionalAtlas.from_config(cfg), cfg)  # the same initialisation train() starts from
    result = train(cfg, progress=False, log=lambda s: None)
    after = _train_chamfer(result.model, cfg)
    assert before / after >= 5.0, (before, after)
    rows = (Path(cfg.out) / "log.csv").read_text().splitlines()
    assert rows[0].startswith("step,epoch,lr,loss,rec") and len(rows) == 1 + 150 // cfg.log_every
    assert float(rows[-1].split(",")[2]) == pytest.approx(3e-5)  # lr x0.1 at 105 and 135
    metrics = json.loads((Path(cfg.out) / "metrics.json").read_text())
    assert metrics["steps"] == 150 and metrics["world_size"] == 1 and metrics["encoder_weights"] == "random"


def _params(model) -> list[torch.Tensor]:
    return [p.detach().clone() for p in model.state_dict().values()]


def test_resume_mid_epoch_equals_uninterrupted(meshes_root, tmp_path):
    kw = dict(epochs=3, batch_size=2, lr_milestones=[2], log_every=1)
    full = train(_cfg(meshes_root, tmp_path / "full", **kw), progress=False, log=lambda s: None)
    cfg = _cfg(meshes_root, tmp_path / "split", **kw)
    first = train(cfg, progress=False, stop_at_step=3, log=lambda s: None)  # epoch 2, after its 1st batch
    assert first.interrupted
    state = torch.load(Path(cfg.out) / "checkpoint.pt", weights_only=False)
    assert (state["epoch"], state["batch_in_epoch"], state["step"]) == (1, 1, 3)
    resumed = train(cfg, resume=True, progress=False, log=lambda s: None)
    assert not resumed.interrupted and resumed.step == full.step == 6
    for a, b in zip(_params(full.model), _params(resumed.model)):
        assert torch.equal(a, b)  # bitwise on the CPU
    logs = [_log_without_timing(Path(d) / "log.csv") for d in (cfg.out, tmp_path / "full")]
    assert logs[0] == logs[1] and len(logs[0]) == 1 + 6  # header + every step, losses identical


def _log_without_timing(path: Path) -> list[list[str]]:
    rows = [line.split(",") for line in path.read_text().splitlines()]
    col = rows[0].index("shapes_per_second")
    return [r[:col] + r[col + 1:] for r in rows]


def _ddp_worker(rank: int, world: int, port: int, cfg_dict: dict, dump: str) -> None:
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank), WORLD_SIZE=str(world),
                      LOCAL_RANK=str(rank))
    torch.set_num_threads(1)
    from mna.distributed import end_rank, teardown_distributed

    try:
        result = train(train_config.from_dict(cfg_dict), progress=False, log=lambda s: None)
        torch.save({"params": _params(result.model), "metrics": result.metrics}, f"{dump}/rank{rank}.pt")
    finally:
        teardown_distributed()
    end_rank(0)  # as `python -m mna.train` ends a rank under torchrun


def test_two_cpu_processes_gloo_end_identical(meshes_root, tmp_path, free_port):
    import torch.multiprocessing as mp

    cfg = _cfg(meshes_root, tmp_path / "ddp", epochs=4, lr_milestones=[3])
    mp.spawn(_ddp_worker, args=(2, free_port, train_config.to_dict(cfg), str(tmp_path)), nprocs=2, join=True)
    r0, r1 = (torch.load(tmp_path / f"rank{r}.pt", weights_only=False) for r in (0, 1))
    torch.manual_seed(cfg.seed)
    init = _params(ConditionalAtlas.from_config(cfg))
    assert any(not torch.equal(a, b) for a, b in zip(init, r0["params"]))  # it trained
    for a, b in zip(r0["params"], r1["params"]):
        assert torch.equal(a, b)
    assert r0["metrics"]["world_size"] == 2 and r0["metrics"]["rank_max_param_diff"] == 0.0
    state = torch.load(Path(cfg.out) / "checkpoint.pt", weights_only=False)
    assert state["per_rank_batch"] == 2 and state["step"] == 4  # 4 items, effective batch 4: 1 step per epoch


@pytest.mark.parametrize("entry", [["mna.train"], ["mna.cli", "train"]], ids=["module", "cli"])
def test_torchrun_two_processes(meshes_root, tmp_path, free_port, entry):
    from train_helpers import subprocess_env

    cfg = _cfg(meshes_root, tmp_path / "tr", epochs=2)
    path = tmp_path / "c.yaml"
    train_config.fit_config_mod.save_yaml(path, train_config.to_dict(cfg))
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nnodes=1", "--nproc_per_node=2",
           "--master_addr=127.0.0.1", f"--master_port={free_port}", "-m", *entry, str(path), "--no-progress"]
    proc = subprocess.run(cmd, env=subprocess_env(), capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-2000:]
    metrics = json.loads((tmp_path / "tr" / "metrics.json").read_text())
    assert metrics["world_size"] == 2 and metrics["rank_max_param_diff"] == 0.0 and metrics["steps"] == 2
    assert proc.stdout.count("done:") == 1  # rank 0 alone reports


def test_end_rank_keeps_the_exit_code_and_buffered_output():
    # a rank ends with os._exit (no finalization); what it printed to the pipes must still arrive
    code = "from mna.distributed import end_rank; print('out', end=''); import sys; print('err', end='', " \
           "file=sys.stderr); end_rank(3)"
    from train_helpers import subprocess_env

    env = {k: v for k, v in subprocess_env().items() if k != "PYTHONUNBUFFERED"}  # block-buffered pipes
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert (proc.returncode, proc.stdout, proc.stderr) == (3, "out", "err")
