"""The fenced code blocks of a Markdown page, as the docs tests read them."""

import re


def code_blocks(markdown: str, lang: str) -> list[str]:
    """The bodies of the page's ```LANG blocks, in page order."""
    return re.findall(rf"```{lang}\n(.*?)```", markdown, flags=re.S)
