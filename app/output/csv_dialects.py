"""The CSV dialects c2n writes: (delimiter, decimal mark). Excel reads a comma-separated file
where the decimal mark is a point; where it is a comma (most of Europe) it wants ``;`` between
fields and reads ``14,877`` as a number. Both are written UTF-8 with a byte-order mark, so a
spreadsheet reads the units (``m/s²``, ``1/rad``) as they are."""

CSV_DIALECTS = {"excel": (",", "."), "excel-semicolon": (";", ",")}
CSV_DIALECT_HELP = (
    "excel: ',' between fields and '.' in numbers; excel-semicolon: ';' and ',' (a spreadsheet set to "
    "a decimal comma); both UTF-8 with a byte-order mark"
)


def dialect_of(delimiter: str) -> str:
    """The dialect to answer a file separated by ``delimiter`` in: Excel's ``;`` means a decimal
    comma; a comma or a tab, a point."""
    return "excel-semicolon" if delimiter == ";" else "excel"
