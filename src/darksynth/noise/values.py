"""One carrier of noise values, from the estimator's output through the profile to the pixel and the manifest.

:class:`NoiseValues` holds every parameter of the table (:mod:`darksynth.noise.components`) by name, each a
tensor shaped ``(*batch, size)``; a parameter that is not given is filled with its neutral value here, and
nowhere else. It is read like a mapping (``values["shot"]``) by the components that draw the noise, and has
the other forms a value takes on its way as views: :meth:`NoiseValues.vector` for the network,
:meth:`NoiseValues.to_json` for profiles and manifests, :meth:`NoiseValues.scalar` for fused kernels.

Values from a profile are kept in float64 so that a profile read and written again keeps its numbers exactly;
the composer casts them to the signal's dtype where the noise is drawn.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

import torch

from darksynth.noise import components as table
from darksynth.noise.components import NoiseComponent, NoiseModel, Parameter

JsonValue = float | list[float]
"""A parameter in JSON: a number for a parameter of size 1, a list of its values otherwise."""


class NoiseValues(Mapping[str, torch.Tensor]):
    """Every noise parameter's values, by name, as tensors shaped ``(*batch, size)``.

    Build one with :meth:`from_values` (numbers, lists or tensors by name; the rest neutral), :meth:`neutral`
    or :func:`values_from_vector`; every entry has the same batch shape, dtype and device.
    """

    __slots__ = ("_neutral", "_tensors")

    def __init__(self, tensors: Mapping[str, torch.Tensor]) -> None:
        self._tensors = _checked(tensors)
        # Which parameters are neutral, asked by the composer at every frame of a stream: computed once (the
        # values are never changed in place; a change makes new values), so a stream on CUDA does not wait for
        # the device at each frame.
        self._neutral: dict[str, bool] = {}

    @classmethod
    def neutral(
        cls,
        batch_shape: tuple[int, ...] = (),
        *,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float64,
    ) -> NoiseValues:
        """Every parameter at its neutral value: no noise at all."""
        return cls.from_values({}, batch_shape=batch_shape, device=device, dtype=dtype)

    @classmethod
    def from_values(
        cls,
        values: Mapping[str, float | Sequence[float] | torch.Tensor],
        *,
        batch_shape: tuple[int, ...] = (),
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float64,
    ) -> NoiseValues:
        """Values by name (a number, a list of ``size`` numbers, or a tensor broadcastable to ``(*batch, size)``;
        one number stands for all values of a vector parameter); parameters not given take their neutral value.

        Raises:
            KeyError: a name that is not a noise parameter.
            ValueError: a value with the wrong number of entries.
        """
        parameters = {p.name: p for p in table.noise_parameters()}
        if device is None:
            # Neutral values go where the given tensors are (a CUDA batch stays on CUDA).
            device = next((v.device for v in values.values() if isinstance(v, torch.Tensor)), None)
        unknown = sorted(set(values) - set(parameters))
        if unknown:
            raise KeyError(f"unknown noise parameter {unknown[0]!r}; known: {', '.join(parameters)}")
        return cls(
            {
                name: _value_tensor(parameter, values.get(name), (*batch_shape, parameter.size), dtype, device)
                for name, parameter in parameters.items()
            }
        )

    @classmethod
    def from_json(cls, noise: Mapping[str, Any]) -> NoiseValues:
        """The values of a JSON object like :meth:`to_json` writes (unchecked: profiles validate first)."""
        return cls.from_values({name: value for name, value in noise.items()})

    def __getitem__(self, name: str) -> torch.Tensor:
        return self._tensors[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._tensors)

    def __len__(self) -> int:
        return len(self._tensors)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, NoiseValues):
            return NotImplemented
        return all(torch.equal(self._tensors[name], other._tensors[name]) for name in self._tensors)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        if not self.batch_shape:
            return f"NoiseValues({self.to_json()})"
        return f"NoiseValues(batch {self.batch_shape}, {', '.join(self._tensors)})"

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return tuple(next(iter(self._tensors.values())).shape[:-1])

    @property
    def device(self) -> torch.device:
        return next(iter(self._tensors.values())).device

    @property
    def dtype(self) -> torch.dtype:
        return next(iter(self._tensors.values())).dtype

    def to(self, device: torch.device | str | None = None, dtype: torch.dtype | None = None) -> NoiseValues:
        """The same values on another device or in another dtype (these very values when nothing changes)."""
        moved = {name: t.to(device=device, dtype=dtype) for name, t in self._tensors.items()}
        if all(moved[name] is t for name, t in self._tensors.items()):
            return self
        return NoiseValues(moved)

    def replace(self, **values: torch.Tensor | float | Sequence[float]) -> NoiseValues:
        """A copy with some parameters set to other values (broadcast to the batch)."""
        tensors = dict(self._tensors)
        for name, value in values.items():
            if name not in tensors:
                raise KeyError(f"unknown noise parameter {name!r}; known: {', '.join(tensors)}")
            old = tensors[name]
            tensors[name] = torch.as_tensor(value, dtype=old.dtype, device=old.device).expand(old.shape).clone()
        return NoiseValues(tensors)

    def map(self, function: Callable[[torch.Tensor], torch.Tensor]) -> NoiseValues:
        """Apply a function to every tensor, e.g. a quantile over the batch: ``values.map(lambda t: t.median(0))``."""
        return NoiseValues({name: function(t) for name, t in self._tensors.items()})

    def clip(self, index: int) -> NoiseValues:
        """The unbatched values of one clip of a batch with one batch dimension."""
        return self.map(lambda t: t[index])

    def scalar(self, name: str) -> float:
        """The single value of a parameter of size 1 in unbatched values: a fused kernel's view."""
        tensor = self._tensors[name]
        if tensor.numel() != 1:
            raise ValueError(f"{name} has {tensor.numel()} values; a scalar view needs exactly one")
        return float(tensor.reshape(()))

    def to_json(self, section: str | None = None) -> dict[str, JsonValue]:
        """Unbatched values as JSON: a number for a parameter of size 1, a list otherwise (profiles, manifests).
        ``section``: only the parameters of that profile section (``noise`` or ``light``), else all."""
        if self.batch_shape:
            raise ValueError(f"only unbatched noise values have a JSON form, these have batch {self.batch_shape}")
        parameters = [p for p in table.noise_parameters() if section is None or table.profile_section(p) == section]
        return {p.name: _json_value(p, self._tensors[p.name]) for p in parameters}

    def is_neutral(self, parameter: Parameter) -> bool:
        """Whether the parameter is at its neutral value in every clip."""
        if parameter.name not in self._neutral:
            self._neutral[parameter.name] = bool((self._tensors[parameter.name] == parameter.neutral).all())
        return self._neutral[parameter.name]

    def is_active(self, component: NoiseComponent) -> bool:
        """Whether the component draws anything: one of its amplitude parameters is not neutral in some clip."""
        return any(not self.is_neutral(p) for p in component.parameters if p.role == "amplitude")


def stacked_values(items: Sequence[NoiseValues]) -> NoiseValues:
    """One batch from unbatched values (or concatenated batches when the items are batched)."""
    join = torch.cat if items[0].batch_shape else torch.stack
    return NoiseValues({name: join([item[name] for item in items]) for name in table.noise_parameter_names()})


def values_from_vector(
    vector: torch.Tensor, noise_model: NoiseModel = "srgb", version: int | None = None
) -> NoiseValues:
    """Split a noise model's flat v ``(*batch, vector_size(noise_model, version))`` into named values; the parameters
    the noise model lacks (or that arrived after ``version``) are neutral (white, uncompressed noise for the
    ``paper`` model). The inverse of :func:`model_vector`."""
    parameters = table.model_parameters(noise_model, version)
    size = sum(p.size for p in parameters)
    if vector.shape[-1] != size:
        raise ValueError(f"a {noise_model} noise vector must end in {size} values, got shape {tuple(vector.shape)}")
    parts = torch.split(vector, [p.size for p in parameters], dim=-1)
    given = {p.name: part for p, part in zip(parameters, parts, strict=True)}
    return NoiseValues.from_values(
        given, batch_shape=tuple(vector.shape[:-1]), device=vector.device, dtype=vector.dtype
    )


def model_vector(values: NoiseValues, noise_model: NoiseModel = "srgb", version: int | None = None) -> torch.Tensor:
    """The flat v of a noise model at a table version, ``(*batch, vector_size(noise_model, version))``: the
    network's view of ``values``."""
    return torch.cat([values[p.name] for p in table.model_parameters(noise_model, version)], dim=-1)


def uncovered_by(values: NoiseValues, fast_path: str) -> list[str]:
    """The set parameters of ``values`` that a fast path declared in the table (:attr:`Parameter.fast_paths`) does
    not draw; empty when it draws these values with the general composer's law."""
    return [p.name for p in table.noise_parameters() if fast_path not in p.fast_paths and not values.is_neutral(p)]


def covered_by(values: NoiseValues, fast_path: str) -> bool:
    """Whether the fast path draws ``values``: every parameter it does not cover is neutral."""
    return not uncovered_by(values, fast_path)


def _checked(tensors: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """``tensors`` in table order, once they are exactly the table's parameters, each shaped ``(*batch, size)`` with
    one batch shape."""
    parameters = table.noise_parameters()
    names = [p.name for p in parameters]
    if set(tensors) != set(names):
        missing = sorted(set(names) - set(tensors))
        extra = sorted(set(tensors) - set(names))
        raise ValueError(f"noise values need exactly the table's parameters; missing {missing}, unknown {extra}")
    batch = tuple(tensors[names[0]].shape[:-1])
    for parameter in parameters:
        shape = tuple(tensors[parameter.name].shape)
        if shape != (*batch, parameter.size):
            raise ValueError(f"noise value {parameter.name} must be shaped {(*batch, parameter.size)}, got {shape}")
    return {name: tensors[name] for name in names}


def _value_tensor(
    parameter: Parameter,
    raw: float | Sequence[float] | torch.Tensor | None,
    shape: tuple[int, ...],
    dtype: torch.dtype,
    device: torch.device | str | None,
) -> torch.Tensor:
    """One parameter's tensor of ``shape`` from a number, a list or a tensor (one number stands for all values of a
    vector parameter); its neutral value where nothing is given."""
    if raw is None:
        return torch.full(shape, parameter.neutral, dtype=dtype, device=device)
    if isinstance(raw, torch.Tensor):
        tensor = raw.to(dtype=dtype, device=device)
    else:
        tensor = torch.tensor([raw] if isinstance(raw, int | float) else list(raw), dtype=dtype, device=device)
    if tensor.dim() == 0:
        tensor = tensor.reshape(1)
    if tensor.shape[-1] not in (1, parameter.size):
        raise ValueError(f"noise value {parameter.name} needs {parameter.size} value(s), got {tuple(tensor.shape)}")
    return tensor.expand(shape).clone()


def _json_value(parameter: Parameter, tensor: torch.Tensor) -> JsonValue:
    """A parameter's unbatched values in JSON: a number for a parameter of size 1, a list otherwise."""
    numbers = [float(v) for v in tensor.tolist()]
    return numbers if parameter.size > 1 else numbers[0]
