"""The experiment harness: fast in-process missions (:mod:`.missionsim`, judged by :mod:`.truth`),
the paper's comparison (:mod:`.paper`), its figures (:mod:`.plots`) and the RL baseline
(:mod:`.rl_baseline`)."""

from .paper import (ALL_METHODS, DEFAULT_PEOPLE, ERROR_CURVE_STEP_S, PAPER_REDUCTION, REFERENCE, ExperimentConfig,
                    ExperimentResult, Task, error_curve, make_tasks, mean_ci95, reductions, run_experiment, run_task,
                    runs_table, summary_text, table_a, table_b, table_c, world_seed, write_outputs)

__all__ = ["ALL_METHODS", "DEFAULT_PEOPLE", "ERROR_CURVE_STEP_S", "PAPER_REDUCTION", "REFERENCE", "ExperimentConfig",
           "ExperimentResult", "Task", "error_curve", "make_tasks", "mean_ci95", "reductions", "run_experiment",
           "run_task", "runs_table", "summary_text", "table_a", "table_b", "table_c", "world_seed", "write_outputs"]
