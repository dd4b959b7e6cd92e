"""Reading back what a run wrote to TensorBoard, as TensorBoard reads it."""

import glob
from pathlib import Path
from typing import Any


def read_hparams(folder: Path) -> tuple[dict[str, Any], list[str]]:
    """The hyperparameters and the metric tags of the HPARAMS tab, as TensorBoard reads them from the event file."""
    from google.protobuf.json_format import MessageToDict
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    from tensorboard.plugins.hparams import plugin_data_pb2

    files = glob.glob(str(folder / "**" / "events.out.tfevents.*"), recursive=True)
    assert len(files) == 1, files
    accumulator = EventAccumulator(files[0])
    accumulator.Reload()

    def plugin_data(tag: str) -> Any:
        return plugin_data_pb2.HParamsPluginData.FromString(accumulator.SummaryMetadata(tag).plugin_data.content)

    start = plugin_data("_hparams_/session_start_info").session_start_info
    hparams = {name: MessageToDict(value) for name, value in start.hparams.items()}
    metrics = [info.name.tag for info in plugin_data("_hparams_/experiment").experiment.metric_infos]
    return hparams, metrics
