"""The page of ``crashstudy report``: one self-contained HTML file (styles, the table's script and one copy
of plotly.js inlined; nothing is fetched when it is opened).

Figures are plain plotly figure dicts (``{"data": [...], "layout": {...}}``), stored in the page as JSON
and drawn by one loader script; the summary table is stored as JSON (columns and rows) and drawn, sorted,
filtered and paged by a small script of its own.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["esc", "figure_div", "page", "table_data", "html_table", "to_json"]

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#222;background:#fafafa}
header{background:#1f3b57;color:#fff;padding:12px 24px}header h1{margin:0;font-size:22px}
header p{margin:4px 0 0;font-size:13px;opacity:.85}
nav{padding:6px 24px;background:#e8edf2;font-size:13px}nav a{margin-right:14px;color:#1f3b57}
main{padding:0 24px 40px}section{background:#fff;border:1px solid #ddd;border-radius:6px;margin:16px 0;padding:8px 16px}
h2{font-size:18px;color:#1f3b57}table{border-collapse:collapse;font-size:12px;margin:6px 0}
th,td{border:1px solid #ddd;padding:2px 6px;text-align:right;white-space:nowrap}th{background:#f0f3f6}
td.t,th.t{text-align:left;white-space:normal}.note{font-size:12px;color:#555}.bad{color:#b00020;font-weight:600}
.good{color:#1b7f3b}.fig{width:100%;min-height:360px}.scroll{overflow-x:auto;max-height:640px;overflow-y:auto}
#cs-table th{cursor:pointer;position:sticky;top:0}#cs-table th.sorted{background:#d6e4f0}
.controls{font-size:13px;margin:6px 0}section p,section ul{font-size:14px}.controls input{width:320px}
"""

TABLE_JS = r"""
(function(){
  var data=JSON.parse(document.getElementById('cs-table-data').textContent);
  var cols=data.columns, rows=data.rows, view=rows.slice(), sortCol=-1, sortDir=1, page=0;
  var tbl=document.getElementById('cs-table'), filt=document.getElementById('cs-filter');
  var size=document.getElementById('cs-pagesize'), info=document.getElementById('cs-info');
  function cell(v){return v===null?'':String(v);}
  function header(){
    var tr=document.createElement('tr');
    cols.forEach(function(c,i){var th=document.createElement('th');th.textContent=c.name+(c.unit?' ['+c.unit+']':'');
      th.title='click to sort';if(c.text)th.className='t';if(i===sortCol)th.className+=' sorted';
      th.onclick=function(){sortDir=(sortCol===i)?-sortDir:1;sortCol=i;apply();};tr.appendChild(th);});
    var th=document.createElement('thead');th.appendChild(tr);return th;}
  function test(term){  // 'col>5', 'col<=2', 'col=failed' or a word found in any cell
    var m=term.match(/^([^<>=!]+)(<=|>=|!=|<|>|=)(.+)$/);
    if(m){var k=-1;cols.forEach(function(c,i){if(c.name===m[1].trim())k=i;});
      if(k<0){cols.forEach(function(c,i){if(k<0&&c.name.indexOf(m[1].trim())>=0)k=i;});}
      if(k>=0){var op=m[2],s=m[3].trim(),x=parseFloat(s);
        return function(r){var v=r[k];if(v===null)return false;
          if(op==='='||op==='!='){var eq=(typeof v==='number'&&!isNaN(x))?v===x:cell(v)===s;return op==='='?eq:!eq;}
          if(typeof v!=='number')return false;
          return op==='<'?v<x:op==='>'?v>x:op==='<='?v<=x:v>=x;};}}
    var w=term.toLowerCase();
    return function(r){for(var i=0;i<r.length;i++){if(cell(r[i]).toLowerCase().indexOf(w)>=0)return true;}return false;};}
  function apply(){
    var terms=filt.value.split(/\s+/).filter(function(t){return t.length;}).map(test);
    view=rows.filter(function(r){return terms.every(function(f){return f(r);});});
    if(sortCol>=0){view.sort(function(a,b){var x=a[sortCol],y=b[sortCol];
      if(x===null)return 1;if(y===null)return -1;return (x<y?-1:x>y?1:0)*sortDir;});}
    page=0;draw();}
  function draw(){
    var n=size.value==='all'?view.length:parseInt(size.value,10),lo=page*n,hi=Math.min(view.length,lo+n);
    tbl.innerHTML='';tbl.appendChild(header());var tb=document.createElement('tbody');
    for(var i=lo;i<hi;i++){var tr=document.createElement('tr');
      view[i].forEach(function(v,j){var td=document.createElement('td');td.textContent=cell(v);
        if(cols[j].text)td.className='t';if(v==='failed')td.className='t bad';tr.appendChild(td);});tb.appendChild(tr);}
    tbl.appendChild(tb);
    info.textContent='rows '+(view.length?lo+1:0)+'-'+hi+' of '+view.length+' matching ('+rows.length+' in the table)';}
  document.getElementById('cs-prev').onclick=function(){if(page>0){page--;draw();}};
  document.getElementById('cs-next').onclick=function(){
    var n=size.value==='all'?view.length:parseInt(size.value,10);if((page+1)*n<view.length){page++;draw();}};
  filt.oninput=apply;size.onchange=function(){page=0;draw();};apply();
})();
"""

FIGURES_JS = r"""
(function(){
  document.querySelectorAll('div.fig[data-fig]').forEach(function(div){
    var f=JSON.parse(document.getElementById(div.getAttribute('data-fig')).textContent);
    Plotly.newPlot(div,f.data,f.layout,{responsive:true,displaylogo:false});});
})();
"""


def esc(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _clean(value: Any) -> Any:
    """``value`` with NaN/inf as ``None`` and numpy scalars/arrays as Python ones (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (np.floating, float)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def to_json(value: Any) -> str:
    """JSON safe to put inside a ``<script>`` element (``</`` escaped)."""
    return json.dumps(_clean(value), separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


class Figures:
    """Numbers the figures of one page and keeps their JSON."""

    def __init__(self) -> None:
        self.count = 0

    def div(self, fig: dict[str, Any], height: int = 420) -> str:
        self.count += 1
        key = f"cs-fig-{self.count}"
        layout = {
            "height": height,
            "margin": {"l": 70, "r": 30, "t": 50, "b": 60},
            "template": None,
            **fig.get("layout", {}),
        }
        data = to_json({"data": fig["data"], "layout": layout})
        return (
            f'<div class="fig" id="{key}-div" data-fig="{key}" style="height:{height}px"></div>'
            f'<script type="application/json" id="{key}">{data}</script>'
        )


def figure_div(figures: Figures, fig: dict[str, Any], height: int = 420) -> str:
    return figures.div(fig, height)


def html_table(
    header: Sequence[str], rows: Sequence[Sequence[Any]], text_cols: Sequence[int] = (0,), cls: str = ""
) -> str:
    """A static table; columns in ``text_cols`` are left-aligned."""

    def td(i: int, v: Any, tag: str) -> str:
        return f'<{tag} class="t">{esc(v)}</{tag}>' if i in text_cols else f"<{tag}>{esc(v)}</{tag}>"

    head = "".join(td(i, h, "th") for i, h in enumerate(header))
    body = "".join("<tr>" + "".join(td(i, v, "td") for i, v in enumerate(r)) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def _num(x: Any) -> Any:
    if isinstance(x, (float, np.floating)):
        f = float(x)
        return float(f"{f:.6g}") if math.isfinite(f) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    return x


def table_data(columns: Sequence[tuple[str, str, bool]], rows: Sequence[Sequence[Any]]) -> str:
    """The JSON of the interactive table: ``columns`` as (name, unit, is text); numbers to 6 digits."""
    cols = [{"name": n, "unit": u, "text": t} for n, u, t in columns]
    return to_json({"columns": cols, "rows": [[_num(v) for v in r] for r in rows]})


def interactive_table(data_json: str) -> str:
    return (
        '<div class="controls">filter: <input id="cs-filter" placeholder="words, or column>value, '
        'status=failed (space = and)"> rows per page: <select id="cs-pagesize"><option>50</option>'
        '<option selected>200</option><option>1000</option><option value="all">all</option></select> '
        '<button id="cs-prev">&lt;</button><button id="cs-next">&gt;</button> <span id="cs-info"></span></div>'
        '<div class="scroll"><table id="cs-table"></table></div>'
        f'<script type="application/json" id="cs-table-data">{data_json}</script>'
    )


def page(
    title: str, subtitle: str, sections: Sequence[tuple[str, str, str]], plotly_js: str, has_table: bool
) -> str:
    """The whole HTML file: ``sections`` as (anchor, heading, body html)."""
    nav = "".join(f'<a href="#{a}">{esc(h)}</a>' for a, h, _ in sections)
    body = "".join(f'<section id="{a}"><h2>{esc(h)}</h2>{b}</section>' for a, h, b in sections)
    table_js = f"<script>{TABLE_JS}</script>" if has_table else ""
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width"><title>{esc(title)}</title>'
        f"<style>{CSS}</style><script>{plotly_js}</script></head><body>"
        f"<header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header><nav>{nav}</nav><main>{body}</main>"
        f"{table_js}<script>{FIGURES_JS}</script></body></html>\n"
    )


def column_unit(ds: Any, column: str) -> str:
    """The unit of a summary column: its own, else its variable's (``peak_force`` for ``peak_force.s1``)."""
    base = column.split(".", 1)[0]
    if column in ds.variables:
        return str(ds[column].attrs.get("units", ""))
    return str(ds[base].attrs.get("units", "")) if base in ds.variables else ""


def shown_unit(unit: str) -> str:
    """A unit as a table shows it: "-" for dimensionless."""
    return "-" if unit == "1" else unit
