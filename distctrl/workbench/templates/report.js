(function () {
  function mark() {
    var imgs = document.querySelectorAll("img");
    var ok = 0;
    for (var i = 0; i < imgs.length; i++) {
      var im = imgs[i];
      var good = im.complete && im.naturalWidth > 0;
      im.setAttribute("data-loaded", good ? "1" : "0");
      im.setAttribute("data-natural-width", String(im.naturalWidth));
      if (good) { ok++; }
    }
    document.body.setAttribute("data-images-loaded", ok + "/" + imgs.length);
  }
  if (document.readyState === "complete") { mark(); } else { window.addEventListener("load", mark); }
})();
