"""A Hydra callback for the Ray cluster tests (``tests/runner/sweep/test_ray_cluster.py``): each
job appends the id of the Ray node it runs on to ``<job dir>/ray_node.txt`` when it starts
(one line per attempt: a job Ray reruns after its node was lost has two)."""

from __future__ import annotations

from pathlib import Path

from hydra.experimental.callback import Callback

NODE_FILE = "ray_node.txt"


class RecordRayNode(Callback):
    def on_job_start(self, config, **kwargs) -> None:
        import ray

        node = ray.get_runtime_context().get_node_id() if ray.is_initialized() else "not-in-ray"
        with open(Path(str(config.hydra.runtime.output_dir)) / NODE_FILE, "a") as file:
            file.write(node + "\n")
