import csv, json, re, os, collections
D = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PLACES = ["entrance", "toilet", "bath", "washroom", "kitchen", "dining", "living-room", "bedroom"]
SPK = ["child", "elderly", "nonnative_zh", "nonnative_de", "nonnative_pt", "asr", "teen", "busy_parent", "guest"]
ok = True
def fail(msg):
    global ok; ok = False; print("FAIL:", msg)
raw = open(os.path.join(D, "speech.csv"), "rb").read()
if b"\r" in raw: fail("CR in speech.csv")
sp = list(csv.DictReader(open(os.path.join(D, "speech.csv"), encoding="utf-8")))
nm = list(csv.DictReader(open(os.path.join(D, "naming.csv"), encoding="utf-8")))
if len(sp) != 576: fail(f"speech rows {len(sp)}")
if len(nm) != len(sp): fail("naming rows differ")
for a, b in zip(sp, nm):
    if (a["place"], a["speaker"], a["sentence"]) != (b["place"], b["speaker"], b["sentence"]): fail("row mismatch " + a["sentence"])
cnt = collections.Counter((r["place"], r["speaker"]) for r in sp)
for p in PLACES:
    for s in SPK:
        if cnt[(p, s)] != 8: fail(f"{p}/{s} has {cnt[(p, s)]}")
if set(r["place"] for r in sp) - set(PLACES): fail("bad place key")
if set(r["speaker"] for r in sp) - set(SPK): fail("bad speaker")
norm = lambda s: " ".join(re.findall(r"[a-z0-9äöüß']+", s.lower().replace("’", "'")))
seen = {}
for r in sp:
    k = (r["place"], norm(r["sentence"]))
    if k in seen: fail(f"duplicate in {r['place']}: {r['sentence']!r} ~ {seen[k]!r}")
    seen[k] = r["sentence"]
# naming consistency
for r in nm:
    if r["names_place"] not in ("yes", "no"): fail("names_place value " + r["names_place"])
    if r["names_place"] == "no" and r["name_said"]: fail("no but name: " + r["sentence"])
    if r["names_place"] == "yes":
        if not r["name_said"]: fail("yes but empty: " + r["sentence"])
        for n in r["name_said"].split("; "):
            if n.lower() not in r["sentence"].lower(): fail(f"name {n!r} not in {r['sentence']!r}")
acc = json.load(open(os.path.join(D, "accepted_names.json"), encoding="utf-8"))
un = json.load(open(os.path.join(D, "unheard_names.json"), encoding="utf-8"))
for J, nmj in ((acc, "accepted"), (un, "unheard")):
    if sorted(J) != sorted(PLACES): fail(nmj + " keys")
for p, names in un.items():
    if not 5 <= len(names) <= 8: fail(f"unheard {p} has {len(names)}")
    for n in names:
        if n != n.lower(): fail("unheard not lower " + n)
        if n not in acc[p]: fail(f"unheard {n!r} not in accepted[{p}]")
        pat = re.compile(r"(?<![a-z0-9])" + re.escape(norm(n)) + r"(?![a-z0-9])")
        hits = [r["sentence"] for r in sp if pat.search(norm(r["sentence"]))]
        if hits: fail(f"unheard {n!r} occurs: {hits[:3]}")
for p, names in acc.items():
    if len(set(names)) != len(names): fail("dup in accepted " + p)
    if any(n != n.lower() for n in names): fail("accepted not lower " + p)
allacc = collections.Counter(n for v in acc.values() for n in v)
dups = [n for n, c in allacc.items() if c > 1]
if dups: fail(f"name in two accepted lists: {dups}")
no = sum(r["names_place"] == "no" for r in nm)
print(f"rows {len(sp)}; name no place: {no} ({no/len(nm):.1%})")
for s in SPK:
    n = sum(r["names_place"] == "no" for r in nm if r["speaker"] == s); print(f"  {s:13s} no-name {n}/64")
for p in PLACES:
    n = sum(r["names_place"] == "no" for r in nm if r["place"] == p); print(f"  {p:13s} no-name {n}/72")
print("ALL CHECKS PASSED" if ok else "CHECKS FAILED")
