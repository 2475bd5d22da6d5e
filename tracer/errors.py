"""Errors raised while loading scenes and patch files (reading them: tracer.formats.source)."""


class SceneError(ValueError):
    """A bad scene or patch file; names the file, line and/or JSON key path.

    ``str(err)`` reads ``teapot.bpt:14: expected 3 numbers per control point, got 2``
    or ``scene.json: objects[0].tranform: unknown key (expected one of: ...)``.
    """

    def __init__(self, message: str, path: str | None = None,
                 line: int | None = None, key: str | None = None):
        super().__init__(message)
        self.message = message
        self.path = path
        self.line = line
        self.key = key

    def __str__(self) -> str:
        where = ""
        if self.path is not None:
            where = str(self.path)
            if self.line is not None:
                where += f":{self.line}"
        elif self.line is not None:
            where = f"line {self.line}"
        parts = [p for p in (where, self.key) if p]
        return ": ".join(parts + [self.message])

    def __reduce__(self):
        # keep path/line/key when the error crosses a process boundary
        return (SceneError, (self.message, self.path, self.line, self.key))

